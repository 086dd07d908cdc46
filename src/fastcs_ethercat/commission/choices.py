"""The PDO group and oversampling factor a rack runs, selected in its YAML.

One YAML describes every terminal of one type and revision, so it selects
one group: the one most of them run (the YAML's own choice on a tie). What
one file cannot say is left for a human, one line each: terminals of one
type running different groups or factors, and a terminal running PDOs that
none of the YAML's groups describes (the IOC then serves its live symbols
that the YAML names, and says which at start).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from fastcs_ethercat.ioc.plan import TerminalPlan
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.selection import select_group, set_oversampling

_T = TypeVar("_T")


@dataclass(slots=True)
class Running:
    """What the terminals of one YAML run, and what a human must decide."""

    group: str | None = None
    factor: int | None = None
    decisions: list[str] = field(default_factory=list)


def running_choice(
    label: str, terminal: TerminalType, slaves: Sequence[TerminalPlan]
) -> Running:
    """The group and factor to select for `slaves` (all of one identity)."""
    found = Running()
    names = ", ".join(slave.slave.name for slave in slaves[:3])
    if terminal.pdo_groups:
        groups = Counter(s.active_group for s in slaves if s.active_group is not None)
        unmatched = [s.slave.name for s in slaves if s.active_group is None]
        if unmatched:
            found.decisions.append(
                f"{label}: {', '.join(unmatched[:3])} run PDOs that none of the "
                "YAML's PDO groups describes: check its PDO assignment in TwinCAT"
            )
        found.group = _most_common(groups, selected_group(terminal))
        if len(groups) > 1:
            shown = ", ".join(f"{g!r} on {n}" for g, n in groups.most_common())
            found.decisions.append(
                f"{label}: terminals run different PDO groups ({shown}); one YAML "
                f"selects one ({found.group!r}): each is served with the group it "
                "runs, or give the others a YAML of their own"
            )
    over = terminal.oversampling
    if over is not None and not over.by_group:
        factors = Counter(s.oversampling for s in slaves if s.oversampling is not None)
        found.factor = _most_common(factors, over.selected_factor)
        if len(factors) > 1:
            shown = ", ".join(f"{f} on {n}" for f, n in factors.most_common())
            found.decisions.append(
                f"{label}: terminals ({names}, ...) sample at different factors "
                f"({shown}); the YAML selects {found.factor}"
            )
    return found


def _most_common(counts: Counter[_T], preferred: _T | None) -> _T | None:
    if not counts:
        return None
    top = max(counts.values())
    if preferred is not None and counts.get(preferred) == top:
        return preferred
    return counts.most_common(1)[0][0]


def with_running(terminal: TerminalType, running: Running) -> TerminalType:
    """`terminal` selecting the group and factor its terminals run."""
    changed = terminal
    if running.group is not None and running.group != selected_group(terminal):
        changed = select_group(changed, running.group)
    over = changed.oversampling
    if (
        running.factor is not None
        and over is not None
        and not over.by_group
        and running.factor != over.selected_factor
        and running.factor in over.factors
    ):
        changed = set_oversampling(changed, running.factor)
    return changed


def selected_group(terminal: TerminalType) -> str | None:
    """The group the YAML selects (its default when it names none)."""
    group = terminal.active_group
    return None if group is None else group.name
