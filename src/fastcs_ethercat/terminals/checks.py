"""Consistency rules a terminal description must keep beyond its field types.

Each problem carries the key path it is about, so the loader can name the
line of the YAML file; the rules are written once here and run on load, on
save and after generation.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Hashable, Sequence
from dataclasses import dataclass

from fastcs_ethercat.terminals.model import SymbolNode, TerminalType
from fastcs_ethercat.terminals.names import CHANNEL, expand

Loc = tuple[str | int, ...]


@dataclass(frozen=True)
class Problem:
    """One broken rule, at a key path inside the terminal's mapping."""

    loc: Loc
    message: str


def terminal_problems(terminal: TerminalType) -> list[Problem]:
    """Every rule `terminal` breaks (empty when it is consistent)."""
    found: list[Problem] = []
    found += _group_problems(terminal)
    for position, node in enumerate(terminal.symbol_nodes):
        found += _symbol_problems(terminal, position, node)
    found += _unique_symbol_names(terminal)
    found += _coe_problems(terminal)
    found += _oversampling_problems(terminal)
    return found


def _duplicates(
    where: Loc, field: str, keys: Sequence[Hashable], message: str
) -> list[Problem]:
    """One problem at each item of the list at `where` whose `field` value
    (`keys`, in list order) another item shares; `message` formats the value."""
    counts = Counter(keys)
    return [
        Problem((*where, at, field), message.format(key))
        for at, key in enumerate(keys)
        if counts[key] > 1
    ]


def _group_problems(terminal: TerminalType) -> list[Problem]:
    groups = terminal.pdo_groups
    names = [g.name for g in groups]
    found = _duplicates(("pdo_groups",), "name", names, "duplicate group {!r}")
    for position, group in enumerate(groups):
        loc: Loc = ("pdo_groups", position)
        for at, index in enumerate(group.symbol_indices):
            if index >= len(terminal.symbol_nodes):
                found.append(
                    Problem(
                        (*loc, "symbol_indices", at),
                        f"symbol index {index} is out of range "
                        f"(there are {len(terminal.symbol_nodes)} symbol_nodes)",
                    )
                )
        if len(set(group.symbol_indices)) != len(group.symbol_indices):
            found.append(Problem((*loc, "symbol_indices"), "repeated symbol index"))
    if groups:
        defaults = [g.name for g in groups if g.is_default]
        if len(defaults) != 1:
            found.append(
                Problem(("pdo_groups",), f"want one default group, got {defaults}")
            )
        if terminal.selected_pdo_group is None:
            found.append(Problem(("pdo_groups",), "selected_pdo_group is missing"))
        elif terminal.selected_pdo_group not in names:
            found.append(
                Problem(
                    ("selected_pdo_group",),
                    f"no PDO group named {terminal.selected_pdo_group!r} "
                    f"(groups: {', '.join(names)})",
                )
            )
    elif terminal.selected_pdo_group is not None:
        found.append(
            Problem(("selected_pdo_group",), "set, but the terminal has no PDO groups")
        )
    return found


def _symbol_problems(
    terminal: TerminalType, position: int, node: SymbolNode
) -> list[Problem]:
    loc: Loc = ("symbol_nodes", position)
    found: list[Problem] = []
    templated = CHANNEL in node.name_template
    if templated != bool(node.channels):
        found.append(
            Problem(
                (*loc, "channels"),
                "channels must be given exactly when name_template has {channel}",
            )
        )
    if len(set(node.channels)) != len(node.channels):
        found.append(Problem((*loc, "channels"), "repeated channel number"))
    if len(node.channels) > 1 and CHANNEL not in node.fastcs_name:
        found.append(
            Problem((*loc, "fastcs_name"), "needs {channel}: the node has channels")
        )
    instances = max(1, len(node.channels))
    if node.pdo_indices and len(node.pdo_indices) != instances:
        found.append(
            Problem(
                (*loc, "pdo_indices"),
                f"want {instances} PDO indices (one per channel), "
                f"got {len(node.pdo_indices)}",
            )
        )
    expected_access = "ro" if node.direction == "input" else "rw"
    if node.access != expected_access:
        found.append(
            Problem(
                (*loc, "access"),
                f"an {node.direction} symbol has access {expected_access}",
            )
        )
    if node.selected and not terminal.selectable(position):
        found.append(
            Problem(
                (*loc, "selected"),
                f"selected, but it belongs only to PDO group(s) "
                f"{terminal.groups_of(position)}, not to the selected group "
                f"{terminal.selected_pdo_group!r}",
            )
        )
    found += _member_problems(loc, node, instances)
    return found


def _member_problems(loc: Loc, node: SymbolNode, instances: int) -> list[Problem]:
    found = _duplicates(
        (*loc, "members"),
        "fastcs_name",
        [m.fastcs_name for m in node.members],
        "duplicate member fastcs_name {!r}",
    )
    end = 0
    for at, member in enumerate(node.members):
        mloc: Loc = (*loc, "members", at)
        if member.bit_offset < end:
            found.append(
                Problem((*mloc, "bit_offset"), "overlaps the member before it")
            )
        end = member.bit_offset + member.bit_size
        if end > node.bit_size:
            found.append(
                Problem(
                    (*mloc, "bit_size"),
                    f"ends at bit {end}, beyond the symbol's {node.bit_size} bits",
                )
            )
        if member.coe and len(member.coe) != instances:
            found.append(
                Problem(
                    (*mloc, "coe"),
                    f"want {instances} CoE addresses (one per channel), "
                    f"got {len(member.coe)}",
                )
            )
    return found


def _unique_symbol_names(terminal: TerminalType) -> list[Problem]:
    """Expanded fastcs names are unique: they become attribute and PV names.

    Symbol names need not be: real ESI files name several PDOs alike (EL1262
    has two "Ch1 Input" PDOs, EL3773 fifteen "L1 Voltage Samples"); such
    symbols are told apart by their PDO index.
    """
    found: list[Problem] = []
    fastcs_seen: dict[str, int] = {}
    for position, node in enumerate(terminal.symbol_nodes):
        loc: Loc = ("symbol_nodes", position)
        for _, channel in node.channel_positions():
            fastcs = expand(node.fastcs_name, channel)
            if fastcs in fastcs_seen and fastcs_seen[fastcs] != position:
                found.append(
                    Problem(
                        (*loc, "fastcs_name"),
                        f"fastcs_name {fastcs!r} is also used by symbol_nodes"
                        f"[{fastcs_seen[fastcs]}]",
                    )
                )
            fastcs_seen.setdefault(fastcs, position)
    return found


def _coe_problems(terminal: TerminalType) -> list[Problem]:
    objects = terminal.coe_objects
    where: Loc = ("coe_objects",)
    found = _duplicates(
        where, "index", [o.index for o in objects], "duplicate CoE index 0x{:04x}"
    )
    found += _duplicates(
        where,
        "fastcs_name",
        [o.fastcs_name for o in objects],
        "duplicate fastcs_name {!r}",
    )
    for position, obj in enumerate(objects):
        subs: Loc = (*where, position, "sub_items")
        found += _duplicates(
            subs,
            "subindex",
            [s.subindex for s in obj.sub_items],
            "duplicate sub-index 0x{:02x}",
        )
        found += _duplicates(
            subs,
            "fastcs_name",
            [s.fastcs_name for s in obj.sub_items],
            "duplicate fastcs_name {!r}",
        )
    return found


def _oversampling_problems(terminal: TerminalType) -> list[Problem]:
    over = terminal.oversampling
    if over is None:
        if any(n.oversampled for n in terminal.symbol_nodes):
            return [Problem(("symbol_nodes",), "oversampled symbols need oversampling")]
        return []
    found: list[Problem] = []
    loc: Loc = ("oversampling",)
    for field in ("default_factor", "selected_factor"):
        value = getattr(over, field)
        if value not in over.factors:
            found.append(
                Problem(
                    (*loc, field), f"{value} is not one of the factors {over.factors}"
                )
            )
    if over.by_group:
        group = terminal.active_group
        if group is not None and group.oversampling_factor not in (
            None,
            over.selected_factor,
        ):
            found.append(
                Problem(
                    (*loc, "selected_factor"),
                    f"the selected PDO group {group.name!r} samples "
                    f"{group.oversampling_factor} times, not {over.selected_factor}",
                )
            )
    return found


def check_terminal(type_name: str, terminal: TerminalType) -> None:
    """Raise ValueError naming the first broken rule (for in-code users)."""
    problems = terminal_problems(terminal)
    if problems:
        first = problems[0]
        path = ".".join(str(p) for p in (type_name, *first.loc))
        raise ValueError(f"{path}: {first.message}")
