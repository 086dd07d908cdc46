"""The PVI structure of every controller (`<path>:PVI`), served on PV Access
by QSRV from the records' `Q:group` info tags.

PVI (what pvi and ophyd-async read to find a device's PVs) is one PVA
structure per controller: a field per attribute with the names of its PVs
(`r` read, `w` write, `x` command) and a field per sub-controller with the
name of its own structure (`d`). FastCS's PVA transport builds it with p4p;
here PV Access is served from the database, so each record carries its
entry as a group field mapped to its `NAME`, and each controller has one
`lsi` record, `<path>:PVI_PV`, whose value is its structure's name: the
structure's metadata and its parent's `d` entry come from it. This is the
layout FastCS's CA transport used before its PVA transport took PVI over.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

from fastcs.attributes import AttrR, AttrRW, AttrW
from fastcs.transports.epics.util import pv_prefix_from_path
from fastcs.util import snake_to_pascal

from fastcs_ethercat.ioc.fastcs_adapter import RBV_SUFFIX

if TYPE_CHECKING:
    from fastcs.controllers import ControllerAPI

PVI_ID: Final = "epics:nt/NTPVI:1.0"
NAME_RECORD_SUFFIX: Final = "_PV"
"""`<path>:PVI_PV`: the record whose value is a controller's PVI name."""
DESC_LENGTH: Final = 40
"""Characters of a record's DESC (dbCommon)."""
MAX_NAME: Final = 60
"""Characters of an EPICS record name, as FastCS counts."""


def add_pvi_groups(controller_apis: list[ControllerAPI]) -> None:
    """Tag the records of every controller (made, not yet loaded) with their
    PVI entries."""
    for api in controller_apis:
        _add_controller(api, None, None)


def _add_controller(
    api: ControllerAPI, parent_pvi: str | None, name: str | None
) -> None:
    from epicsdbbuilder import LookupRecord
    from softioc import builder

    prefix = pv_prefix_from_path(api.path)
    pvi = f"{prefix}:PVI"
    if len(pvi + NAME_RECORD_SUFFIX) <= MAX_NAME:
        group: dict[str, Any] = {
            pvi: {
                "+id": PVI_ID,
                "display.description": {"+type": "plain", "+channel": "DESC"},
                "": {"+type": "meta", "+channel": "VAL"},
            }
        }
        if parent_pvi is not None and name is not None:
            group[parent_pvi] = {_field(name, "d"): _entry(name, "d", "VAL")}
        record = builder.longStringIn(
            pvi + NAME_RECORD_SUFFIX,
            initial_value=pvi,
            DESC=(api.description or "The PVs of this controller")[:DESC_LENGTH],
        )
        record.add_info("Q:group", group)
    for attr_name, attribute in api.attributes.items():
        if not attribute.enabled:  # no record: its name is too long
            continue
        pv = f"{prefix}:{snake_to_pascal(attr_name)}"
        for record_name, access in _records(attribute, pv):
            try:
                tagged: Any = LookupRecord(record_name)
            except KeyError:
                continue
            field = _field(attr_name, access)
            tagged.add_info("Q:group", {pvi: {field: _entry(attr_name, access)}})
    for method_name in api.command_methods:
        pv = f"{prefix}:{snake_to_pascal(method_name)}"
        try:
            command: Any = LookupRecord(pv)
        except KeyError:
            continue
        command.add_info(
            "Q:group", {pvi: {_field(method_name, "x"): _entry(method_name, "x")}}
        )
    for key, sub_api in api.sub_apis.items():
        child = f"__{int(key)}" if sub_api.path[-1].isdigit() else key.lower()
        _add_controller(sub_api, pvi, child)


def _records(attribute: Any, pv: str) -> list[tuple[str, str]]:
    """(record name, PVI access) of each record serving `attribute`."""
    if isinstance(attribute, AttrRW):
        return [(pv + RBV_SUFFIX, "r"), (pv, "w")]
    if isinstance(attribute, AttrR):
        return [(pv, "r")]
    if isinstance(attribute, AttrW):
        return [(pv, "w")]
    return []


def _field(name: str, access: str) -> str:
    return f"value.{name}.{access}"


def _entry(name: str, access: str, channel: str = "NAME") -> dict[str, str]:
    """A group field holding the record's `channel` (its name by default),
    posted only when that field itself changes."""
    return {"+channel": channel, "+type": "plain", "+trigger": _field(name, access)}
