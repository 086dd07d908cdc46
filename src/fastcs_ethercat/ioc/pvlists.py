"""The PVs served, as an Archiver Appliance list and an autosave request file.

Both are made from `root.pvs()` (each PV's access, type and source), never
from PV names, so they follow whatever naming scheme serves:

- archiver: the JSON array the Archiver Appliance's `archivePV` call takes
  (`[{"pv": ..., "samplingperiod": "0.1", "samplingmethod": "MONITOR"}]`,
  POSTed to `mgmt/bpl/archivePV`). Values read from the PLC (inputs and the
  `_RBV` of outputs), setpoints, CoE parameters and the IOC's states, flags
  and texts are monitored (every change kept, at most once per sampling
  period: the poll period for PLC values); the slow diagnostics the IOC
  counts (frame and error counters, rates, cycle times) are scanned every
  `DIAGNOSTICS_SCAN_S`. Commands are not archived.
- autosave: an autosave request file (`.req`, one PV a line, its VAL field)
  of what an operator sets: output setpoints and writable CoE parameters.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:  # the CLI imports this module before FastCS is needed
    from fastcs_ethercat.ioc.controllers.tree import PvEntry

IOC_SOURCE: Final = "ioc"
COMMAND_SOURCE: Final = "command"
COE_SOURCE_PREFIX: Final = "CoE:"
DIAGNOSTICS_SCAN_S: Final = 10.0
COE_MONITOR_S: Final = 1.0
STATE_TYPES: Final = frozenset({"Bool", "Enum", "String"})
"""Datatypes of the IOC's own PVs that are states, flags or texts: monitored."""
ARCHIVER_FILE: Final = "archiver.json"
AUTOSAVE_FILE: Final = "autosave.req"


class PvListFormat(StrEnum):
    """What `ioc --list-pvs --format` prints."""

    TEXT = "text"
    ARCHIVER = "archiver"
    AUTOSAVE = "autosave"


def _from_target(entry: PvEntry) -> bool:
    """A value of a TwinCAT symbol (polled), not the IOC's or a CoE object's."""
    return entry.source not in (IOC_SOURCE, COMMAND_SOURCE) and not _is_coe(entry)


def _is_coe(entry: PvEntry) -> bool:
    return entry.source.startswith(COE_SOURCE_PREFIX)


def archiver_items(
    entries: Sequence[PvEntry], poll_rate_hz: float
) -> list[dict[str, str]]:
    """One archivePV request item per readable PV."""
    items: list[dict[str, str]] = []
    for entry in entries:
        if "r" not in entry.access:
            continue  # commands and write-only PVs hold nothing to archive
        if _from_target(entry):
            method, period = "MONITOR", 1.0 / poll_rate_hz
        elif _is_coe(entry) or entry.datatype in STATE_TYPES:
            method, period = "MONITOR", COE_MONITOR_S
        else:
            method, period = "SCAN", DIAGNOSTICS_SCAN_S
        items.append(
            {
                "pv": entry.name,
                "samplingperiod": f"{period:g}",
                "samplingmethod": method,
            }
        )
    return items


def archiver_text(entries: Sequence[PvEntry], poll_rate_hz: float) -> str:
    """The archivePV JSON body: one PV a line, ready for `curl --data @FILE`."""
    lines = [json.dumps(item) for item in archiver_items(entries, poll_rate_hz)]
    return "[\n" + ",\n".join(lines) + "\n]\n"


def autosave_names(entries: Sequence[PvEntry]) -> list[str]:
    """Output setpoints and writable CoE parameters."""
    return [
        entry.name
        for entry in entries
        if entry.access == "rw" and (_from_target(entry) or _is_coe(entry))
    ]


def autosave_text(entries: Sequence[PvEntry], prefix: str) -> str:
    """An autosave request file (the VAL field of each PV)."""
    header = (
        f"# autosave request of {prefix}: output setpoints and CoE parameters\n"
        "# (written by fastcs-ethercat; one PV a line, its VAL field)\n"
    )
    return header + "".join(f"{name}\n" for name in autosave_names(entries))


def pv_list_text(
    entries: Sequence[PvEntry], fmt: PvListFormat, prefix: str, poll_rate_hz: float
) -> str:
    """What `ioc --list-pvs --format FMT` prints."""
    if fmt is PvListFormat.ARCHIVER:
        return archiver_text(entries, poll_rate_hz)
    if fmt is PvListFormat.AUTOSAVE:
        return autosave_text(entries, prefix)
    return "".join(f"{entry.line()}\n" for entry in entries)


def write_pv_lists(
    folder: Path, entries: Sequence[PvEntry], prefix: str, poll_rate_hz: float
) -> list[Path]:
    """`archiver.json` and `autosave.req` in `folder` (made if missing)."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in (
        (ARCHIVER_FILE, archiver_text(entries, poll_rate_hz)),
        (AUTOSAVE_FILE, autosave_text(entries, prefix)),
    ):
        path = folder / name
        path.write_text(text, encoding="utf-8")
        written.append(path)
    return written


__all__ = [
    "PvListFormat",
    "archiver_items",
    "archiver_text",
    "autosave_names",
    "autosave_text",
    "pv_list_text",
    "write_pv_lists",
]
