"""The controllers' own diagnostics PVs (statistics, states, counters) updated
only when their value changed: an update costs ~200 µs and the scans run
every second."""

from __future__ import annotations

from typing import Any

from fastcs.attributes import AttrR


async def update_if_changed(attr: AttrR[Any, Any], value: Any) -> None:
    """`attr.update(value)` unless the attribute already holds that value."""
    validated = attr.datatype.validate(value)
    if not attr.datatype.equal(attr.get(), validated):
        await attr.update(validated)
