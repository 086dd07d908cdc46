"""The lines `init` ends with: the rack by type and revision, where each
YAML came from, the PVs against the name budget, what changed on the rack
since the last run and what a human must decide."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

from fastcs_ethercat.commission.layout import TERMINALS_DIR
from fastcs_ethercat.commission.run import Outcome
from fastcs_ethercat.commission.sources import Origin

WARNINGS_SHOWN = 5
"""The IOC's own start warnings shown; the rest counted."""


def summary_lines(outcome: Outcome, out: Path, check: bool) -> Iterator[str]:
    plan = outcome.plan
    count = sum(len(master.terminals) for master in plan.masters)
    yield f"rack: {count} terminals on {len(plan.masters)} master(s)"
    for item in outcome.described:
        shown = [] if item.origin in (Origin.KEPT, Origin.SHIPPED) else [item.source]
        if item.origin is Origin.NEAREST_YAML and item.terminal is not None:
            shown = [f"revision 0x{item.terminal.identity.revision_number:08x}"]
        if item.file_name is not None:
            shown.insert(0, f"{TERMINALS_DIR}/{item.file_name}")
        where = ", ".join(part for part in shown if part) or "-"
        yield (
            f"  {len(item.slaves):4d} x {item.type_name} revision "
            f"0x{item.revision:08x}: {_origin(item.origin)} ({where})"
        )
    served = outcome.served
    yield f"PVs: {served.pv_count}; {served.room}; {served.screens} screens"
    if not outcome.first_run:
        yield _heading("changes on the rack since the last init", outcome.changes)
        yield from (f"  {change.line()}" for change in outcome.changes)
    yield _heading("needs a human decision", outcome.decisions)
    yield from (f"  {line}" for line in outcome.decisions)
    if served.warnings:
        yield f"the IOC will warn at start ({len(served.warnings)}):"
        yield from (f"  {line}" for line in served.warnings[:WARNINGS_SHOWN])
        if len(served.warnings) > WARNINGS_SHOWN:
            yield f"  ... and {len(served.warnings) - WARNINGS_SHOWN} more"
    if check:
        yield _heading(f"files of {out} that init would change", outcome.differences)
        yield from (f"  {line}" for line in outcome.differences)
    elif outcome.differences:
        yield f"wrote {out}: {len(outcome.differences)} files added or changed"
    else:
        yield f"{out} is up to date"


def _origin(origin: Origin) -> str:
    return "YAML already in DIR" if origin is Origin.KEPT else origin.value


def _heading(text: str, items: Sequence[object]) -> str:
    return f"{text}: {'none' if not items else len(items)}"
