"""Absolute deadbands per symbol: noise below them is not published.

An analog input's low bits change every cycle; on a rack of them nearly every
value of every poll is new, and each one costs a post and a monitor event on
every client. A deadband works as an EPICS record's MDEL: a value is posted
only when it differs from the last one posted by more than the deadband (in
the symbol's own units, as read from the PLC), so a slow drift still shows
once it has moved that far.

The IOC configuration maps glob patterns over TwinCAT symbol names (`Term 5
(EL3104).AI Standard Channel 1.Value`) to deadbands; the first pattern that
matches wins. Only numbers (FastCS `Int` and `Float`) have one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from fnmatch import fnmatchcase
from typing import Any

from fastcs.attributes import Attribute
from fastcs.datatypes import Float, Int

from fastcs_ethercat.ioc.attributes import PointRef


@dataclass(frozen=True)
class Deadbands:
    """Pattern -> deadband, in the order given."""

    rules: tuple[tuple[str, float], ...] = ()

    @classmethod
    def of_config(cls, patterns: Mapping[str, float]) -> Deadbands:
        return cls(tuple((pattern, float(band)) for pattern, band in patterns.items()))

    def of_symbol(self, symbol: str) -> float:
        """The deadband of a TwinCAT symbol (0: every change is posted)."""
        for pattern, band in self.rules:
            if fnmatchcase(symbol, pattern):
                return band
        return 0.0

    def of_attribute(self, attribute: Attribute[Any, Any]) -> float:
        """The deadband of a polled number's attribute, else 0."""
        if not self.rules or not attribute.has_io_ref():
            return 0.0
        ref = attribute.io_ref
        if not isinstance(ref, PointRef):
            return 0.0
        if not isinstance(attribute.datatype, Int | Float):
            return 0.0
        return self.of_symbol(ref.point.symbol)
