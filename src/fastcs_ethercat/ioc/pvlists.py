"""The PVs served, as an Archiver Appliance list and an autosave request file.

Both are made from `root.pvs()` (each PV's access, type and source), never
from PV names, so they follow whatever naming scheme serves:

- archiver: the JSON array the Archiver Appliance's `archivePV` call takes
  (`[{"pv": ..., "samplingperiod": "0.1", "samplingmethod": "MONITOR"}]`,
  POSTed to `mgmt/bpl/archivePV`), by kind (`ArchiverPolicy`):
  values from the PLC and output setpoints are monitored at the poll period
  (the IOC posts a value only once it moved by its configured deadband, so
  the archive keeps the same changes); status bits and states (Bool, Enum)
  and CoE parameters are monitored on change; texts are archived over PV
  Access (`pva://`), where a text is a string, not the bytes CA carries; the
  slow diagnostics the IOC counts (frame and error counters, rates, cycle
  times) are scanned every `DIAGNOSTICS_SCAN_S`. Raw twins of scaled values
  and the `_RBV` readbacks of outputs only when asked; commands never. The
  config's include/exclude patterns (globs over the PV names below the
  prefix) choose among the rest.
- autosave: an autosave request file (`.req`, one `PV.FIELD` a line) of
  what an operator sets on the records and the IOC alone holds: alarm limits
  and severities, hysteresis, deadbands, DESC, by record type
  (`OPERATOR_FIELDS`). Never a VAL: an output's value is the PLC's (restored
  at boot it would be written to the PLC, and a command bit such as `Tara`
  or `SetCounter` would fire), an input's is the next poll's, and a CoE
  parameter's is stored in the terminal itself (restored, it would be
  written to the terminal at every start). The IOC has no soft settings of
  its own to add: what it is told lives in its config file.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from fnmatch import fnmatchcase
from pathlib import Path
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:  # the CLI imports this module before FastCS is needed
    from fastcs_ethercat.ioc.controllers.tree import PvEntry

IOC_SOURCE: Final = "ioc"
COMMAND_SOURCE: Final = "command"
COE_SOURCE_PREFIX: Final = "CoE:"
DIAGNOSTICS_SCAN_S: Final = 10.0
COE_MONITOR_S: Final = 1.0
STATE_TYPES: Final = frozenset({"Bool", "Enum"})
"""Datatypes of status bits and states: monitored on change."""
TEXT_TYPE: Final = "String"
SCALED_TYPES: Final = frozenset({"ExactFloat", "IntegralFloat"})
"""A scaled value's types: an `Int` of the same symbol beside one is its raw twin."""
RBV_SUFFIX: Final = "_RBV"
PVA_SCHEME: Final = "pva://"
"""The Archiver Appliance reads a PV named so over PV Access."""
ARCHIVER_FILE: Final = "archiver.json"
AUTOSAVE_FILE: Final = "autosave.req"
NUMBER_FIELDS: Final = (
    "HIHI", "HIGH", "LOW", "LOLO", "HHSV", "HSV", "LSV", "LLSV",
    "HYST", "MDEL", "ADEL",
)  # fmt: skip
"""Alarm limits, their severities, hysteresis and deadbands of a number."""
STATE_FIELDS: Final = ("ZSV", "OSV", "COSV")
"""The severities of a bit's two states and of a change of state."""
OPERATOR_FIELDS: Final[dict[str, tuple[str, ...]]] = {
    "ai": (*NUMBER_FIELDS, "DESC"),
    "ao": (*NUMBER_FIELDS, "DESC"),
    "longin": (*NUMBER_FIELDS, "DESC"),
    "longout": (*NUMBER_FIELDS, "DESC"),
    "bi": (*STATE_FIELDS, "DESC"),
    "bo": (*STATE_FIELDS, "DESC"),
    "mbbi": ("UNSV", "COSV", "DESC"),
    "mbbo": ("UNSV", "COSV", "DESC"),
    "waveform": ("DESC",),
}
"""Record type -> the operator's fields autosave keeps (never VAL)."""


class PvListFormat(StrEnum):
    """What `ioc --list-pvs --format` prints."""

    TEXT = "text"
    ARCHIVER = "archiver"
    AUTOSAVE = "autosave"


@dataclass(frozen=True)
class ArchiverPolicy:
    """What goes into the archiver list (the config's `archiver:` key)."""

    raw: bool = False
    """Archive the raw counts beside each scaled value too."""
    readbacks: bool = False
    """Archive the `_RBV` readback of each output too (its setpoint always)."""
    include: tuple[str, ...] = ("*",)
    """Globs over the PV names below the prefix: only these are archived..."""
    exclude: tuple[str, ...] = ()
    """...except these."""

    def chooses(self, name: str, prefix: str) -> bool:
        below = name.removeprefix(f"{prefix}:")
        return any(fnmatchcase(below, p) for p in self.include) and not any(
            fnmatchcase(below, p) for p in self.exclude
        )


def _raw_twins(entries: Sequence[PvEntry]) -> set[str]:
    """The `Int` PVs of symbols that also have a scaled PV."""
    scaled = {e.source for e in entries if e.datatype in SCALED_TYPES}
    return {
        e.name
        for e in entries
        if e.datatype == "Int" and e.source in scaled and _from_target(e)
    }


def _from_target(entry: PvEntry) -> bool:
    """A value of a TwinCAT symbol (polled), not the IOC's or a CoE object's."""
    return entry.source not in (IOC_SOURCE, COMMAND_SOURCE) and not _is_coe(entry)


def _is_coe(entry: PvEntry) -> bool:
    return entry.source.startswith(COE_SOURCE_PREFIX)


def archiver_items(
    entries: Sequence[PvEntry],
    poll_rate_hz: float,
    policy: ArchiverPolicy | None = None,
    prefix: str = "",
) -> list[dict[str, str]]:
    """One archivePV request item per PV the policy archives."""
    policy = policy or ArchiverPolicy()
    raw = set() if policy.raw else _raw_twins(entries)
    items: list[dict[str, str]] = []
    for entry in entries:
        if "r" not in entry.access:
            continue  # commands and write-only PVs hold nothing to archive
        if entry.name in raw or not policy.chooses(entry.name, prefix):
            continue
        if not policy.readbacks and entry.name.endswith(RBV_SUFFIX):
            continue  # the setpoint is archived; the PLC's copy only if asked
        name, method, period = entry.name, "SCAN", DIAGNOSTICS_SCAN_S
        if entry.datatype == TEXT_TYPE:
            name, method, period = PVA_SCHEME + entry.name, "MONITOR", COE_MONITOR_S
        elif entry.datatype in STATE_TYPES or _is_coe(entry):
            method, period = "MONITOR", COE_MONITOR_S
        elif _from_target(entry):
            method, period = "MONITOR", 1.0 / poll_rate_hz
        items.append(
            {"pv": name, "samplingperiod": f"{period:g}", "samplingmethod": method}
        )
    return items


def archiver_text(
    entries: Sequence[PvEntry],
    poll_rate_hz: float,
    policy: ArchiverPolicy | None = None,
    prefix: str = "",
) -> str:
    """The archivePV JSON body: one PV a line, ready for `curl --data @FILE`."""
    items = archiver_items(entries, poll_rate_hz, policy, prefix)
    lines = [json.dumps(item) for item in items]
    return "[\n" + ",\n".join(lines) + "\n]\n"


def autosave_names(entries: Sequence[PvEntry]) -> list[str]:
    """`PV.FIELD` of each operator setting of each served record (commands
    have none)."""
    return [
        f"{entry.name}.{field}"
        for entry in entries
        for field in OPERATOR_FIELDS.get(entry.record, ())
    ]


def autosave_text(entries: Sequence[PvEntry], prefix: str) -> str:
    """An autosave request file of the operator's settings, no value."""
    header = (
        f"# autosave request of {prefix}: alarm limits, severities, deadbands,"
        " DESC\n"
        "# (written by fastcs-ethercat; one PV.FIELD a line; never a VAL)\n"
    )
    return header + "".join(f"{name}\n" for name in autosave_names(entries))


def pv_list_text(
    entries: Sequence[PvEntry],
    fmt: PvListFormat,
    prefix: str,
    poll_rate_hz: float,
    policy: ArchiverPolicy | None = None,
) -> str:
    """What `ioc --list-pvs --format FMT` prints."""
    if fmt is PvListFormat.ARCHIVER:
        return archiver_text(entries, poll_rate_hz, policy, prefix)
    if fmt is PvListFormat.AUTOSAVE:
        return autosave_text(entries, prefix)
    return "".join(f"{entry.line()}\n" for entry in entries)


def write_pv_lists(
    folder: Path,
    entries: Sequence[PvEntry],
    prefix: str,
    poll_rate_hz: float,
    policy: ArchiverPolicy | None = None,
) -> list[Path]:
    """`archiver.json` and `autosave.req` in `folder` (made if missing)."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in (
        (ARCHIVER_FILE, archiver_text(entries, poll_rate_hz, policy, prefix)),
        (AUTOSAVE_FILE, autosave_text(entries, prefix)),
    ):
        path = folder / name
        path.write_text(text, encoding="utf-8")
        written.append(path)
    return written


__all__ = [
    "OPERATOR_FIELDS",
    "ArchiverPolicy",
    "PvListFormat",
    "archiver_items",
    "archiver_text",
    "autosave_names",
    "autosave_text",
    "pv_list_text",
    "write_pv_lists",
]
