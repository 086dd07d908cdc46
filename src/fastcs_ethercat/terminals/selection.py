"""Switching the PDO group of a terminal, with the `selected` flags it implies."""

from __future__ import annotations

from fastcs_ethercat.terminals.model import TerminalType


class UnknownGroupError(ValueError):
    """The terminal has no PDO group of that name."""


def select_group(terminal: TerminalType, group_name: str) -> TerminalType:
    """A copy with `group_name` selected.

    Symbols of the new group are selected, symbols only in other groups are
    deselected, symbols in no group keep their flag. An oversampling factor
    that follows the group (ELM37xx) follows it.
    """
    names = [g.name for g in terminal.pdo_groups]
    if group_name not in names:
        offered = ", ".join(repr(n) for n in names) if names else "none"
        raise UnknownGroupError(f"no PDO group {group_name!r} (groups: {offered})")
    changed = terminal.model_copy(deep=True)
    changed.selected_pdo_group = group_name
    for position, node in enumerate(changed.symbol_nodes):
        groups = changed.groups_of(position)
        if groups:
            node.selected = group_name in groups
    over = changed.oversampling
    group = changed.group(group_name)
    if over is not None and over.by_group and group.oversampling_factor is not None:
        over.selected_factor = group.oversampling_factor
    return changed
