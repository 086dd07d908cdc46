"""The engineer's choices in a terminal, one function per kind of choice.

The CLI (`select-group`, `select`, `coe`, `units`, `severity`) and the web
editor call these same
functions, so a choice made in either gives the same file. Each returns a
changed copy, checked against the terminal rules; a choice that cannot be
made raises `SelectionError` with a one-line reason.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from pydantic import ValidationError

from fastcs_ethercat.terminals.checks import terminal_problems
from fastcs_ethercat.terminals.meaning import is_status
from fastcs_ethercat.terminals.model import (
    UNIT_CHOICES,
    CoeObject,
    SeverityName,
    SymbolMember,
    SymbolNode,
    TerminalType,
)
from fastcs_ethercat.terminals.names import CHANNEL, expand

FASTCS_NAME = re.compile(r"^[a-z][a-z0-9_]*(\{channel\}[a-z0-9_]*)*$")


class SelectionError(ValueError):
    """A choice that cannot be made (unknown name, wrong group, bad name)."""


class UnknownGroupError(SelectionError):
    """The terminal has no PDO group of that name."""


def _checked(terminal: TerminalType) -> TerminalType:
    problems = terminal_problems(terminal)
    if problems:
        first = problems[0]
        where = ".".join(str(part) for part in first.loc)
        raise SelectionError(f"{where}: {first.message}")
    return terminal


def group_name(terminal: TerminalType, wanted: str) -> str:
    """`wanted`, or the one group whose name matches it ignoring case."""
    names = [g.name for g in terminal.pdo_groups]
    if wanted in names:
        return wanted
    folded = [n for n in names if n.casefold() == wanted.casefold()]
    return folded[0] if len(folded) == 1 else wanted


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


def find_symbol(terminal: TerminalType, wanted: str) -> int:
    """Position of the symbol node named `wanted`: its `name_template` (any
    case) or its `fastcs_name`. A channel's own name is refused with the
    node to name instead, since a node is selected for all its channels."""
    nodes = terminal.symbol_nodes
    exact = [
        i for i, n in enumerate(nodes) if wanted in (n.name_template, n.fastcs_name)
    ]
    if not exact:
        folded = wanted.casefold()
        exact = [i for i, n in enumerate(nodes) if n.name_template.casefold() == folded]
    if len(exact) == 1:
        return exact[0]
    if len(exact) > 1:
        which = ", ".join(nodes[i].fastcs_name for i in exact)
        raise SelectionError(
            f"{len(exact)} symbols are called {wanted!r}; name one by its "
            f"fastcs_name ({which})"
        )
    for node in nodes:
        if wanted in node.names() and CHANNEL in node.name_template:
            raise SelectionError(
                f"{wanted!r} is one channel of {node.name_template!r}: a symbol is "
                "selected for all its channels, name the symbol"
            )
    offered = ", ".join(repr(n.name_template) for n in nodes) or "none"
    raise SelectionError(f"no symbol {wanted!r} (symbols: {offered})")


def select_symbols(
    terminal: TerminalType, wanted: Sequence[str], on: bool = True
) -> TerminalType:
    """A copy with the named symbol nodes selected (or deselected)."""
    changed = terminal.model_copy(deep=True)
    for name in wanted:
        position = find_symbol(changed, name)
        if on and not changed.selectable(position):
            groups = ", ".join(repr(g) for g in changed.groups_of(position))
            raise SelectionError(
                f"{changed.symbol_nodes[position].name_template!r} belongs to PDO "
                f"group {groups}, not to the selected "
                f"{changed.selected_pdo_group!r}: switch with select-group first"
            )
        changed.symbol_nodes[position].selected = on
    return _checked(changed)


def parse_coe_target(text: str) -> tuple[int, int | None]:
    """`0x8000`, `8000`, `#x8000`, `0x8000:11`, `8000:0x11` -> (index, sub).

    Indices and sub-indices are hex, as every CoE listing writes them."""
    index_text, _, sub_text = text.strip().partition(":")

    def number(part: str, limit: int) -> int:
        digits = part.strip().lower().removeprefix("#x").removeprefix("0x")
        if not re.fullmatch(r"[0-9a-f]+", digits) or int(digits, 16) > limit:
            raise SelectionError(
                f"{text!r} is not a CoE address (hex INDEX[:SUB], e.g. 0x8000:11)"
            )
        return int(digits, 16)

    index = number(index_text, 0xFFFF)
    return index, number(sub_text, 0xFF) if sub_text else None


def _coe_object(terminal: TerminalType, index: int) -> CoeObject:
    for obj in terminal.coe_objects:
        if obj.index == index:
            return obj
    raise SelectionError(f"no CoE object 0x{index:04x} in this terminal")


def select_coe(
    terminal: TerminalType, targets: Sequence[str], on: bool = True
) -> TerminalType:
    """A copy with CoE objects or single sub-indices selected (or not).

    `0x8000` selects the object with every sub-index; `0x8000:11` selects
    that sub-index (and its object; when the object was off, only that
    sub-index). Off: `0x8000` drops the object, `0x8000:11` the sub-index
    (and the object with its last one, which then forgets its sub-index
    flags: an unselected object is written as it was generated)."""
    changed = terminal.model_copy(deep=True)
    for target in targets:
        index, subindex = parse_coe_target(target)
        obj = _coe_object(changed, index)
        if subindex is None:
            obj.selected = on
            for sub in obj.sub_items:
                sub.selected = True
            continue
        sub = next((s for s in obj.sub_items if s.subindex == subindex), None)
        if sub is None:
            offered = ", ".join(f"{s.subindex:02x}" for s in obj.sub_items) or "none"
            raise SelectionError(
                f"CoE object 0x{index:04x} has no sub-index {subindex:02x} "
                f"(sub-indices: {offered})"
            )
        if on and not obj.selected:
            for other in obj.sub_items:
                other.selected = other is sub
        sub.selected = on
        obj.selected = any(s.selected for s in obj.sub_items)
        if not obj.selected:  # off as a whole: no sub-index flags to remember
            for other in obj.sub_items:
                other.selected = True
    return _checked(changed)


def set_oversampling(terminal: TerminalType, factor: int) -> TerminalType:
    """A copy sampling `factor` times per cycle (one of the offered factors)."""
    over = terminal.oversampling
    if over is None:
        raise SelectionError("this terminal does not oversample")
    if over.by_group:
        raise SelectionError(
            "the oversampling factor follows the PDO group here: select the group"
        )
    if factor not in over.factors:
        offered = ", ".join(map(str, over.factors))
        raise SelectionError(f"{factor} is not an offered factor ({offered})")
    changed = terminal.model_copy(deep=True)
    assert changed.oversampling is not None
    changed.oversampling.selected_factor = factor
    return _checked(changed)


def check_fastcs_name(name: str, channels: bool) -> None:
    """A snake_case attribute name; `{channel}` where the node has channels."""
    if not FASTCS_NAME.match(name):
        raise SelectionError(
            f"{name!r} is not a fastcs_name: lower-case letters, digits and _, "
            "starting with a letter"
        )
    if channels and CHANNEL not in name:
        raise SelectionError(f"{name!r} needs {CHANNEL}: the symbol has channels")


def rename_symbol(terminal: TerminalType, position: int, name: str) -> TerminalType:
    """A copy whose symbol node at `position` has the fastcs_name `name`."""
    node: SymbolNode = terminal.symbol_nodes[position]
    check_fastcs_name(name, len(node.channels) > 1)
    changed = terminal.model_copy(deep=True)
    changed.symbol_nodes[position].fastcs_name = name
    taken = {
        expand(other.fastcs_name, channel)
        for at, other in enumerate(changed.symbol_nodes)
        if at != position
        for _, channel in other.channel_positions()
    }
    clash = [
        expand(name, ch)
        for _, ch in node.channel_positions()
        if expand(name, ch) in taken
    ]
    if clash:
        raise SelectionError(f"{clash[0]!r} is already the name of another symbol")
    return _checked(changed)


def rename_coe(terminal: TerminalType, index: int, name: str) -> TerminalType:
    """A copy whose CoE object `index` has the fastcs_name `name`."""
    check_fastcs_name(name, False)
    if any(o.fastcs_name == name and o.index != index for o in terminal.coe_objects):
        raise SelectionError(f"{name!r} is already the name of another CoE object")
    changed = terminal.model_copy(deep=True)
    _coe_object(changed, index).fastcs_name = name
    return _checked(changed)


def find_member(node: SymbolNode, wanted: str | None, status: bool = False) -> int:
    """Position of the member named `wanted` (its ESI name, any case, or its
    fastcs_name) in `node`; without a name, the node's one value (or with
    `status`, its one status bit or field)."""
    members = node.members
    if wanted is None:
        fitting = [i for i, m in enumerate(members) if is_status(m) == status]
        if len(fitting) == 1:
            return fitting[0]
        raise SelectionError(
            f"{node.name_template!r} has {len(fitting)} "
            f"{'status bits' if status else 'values'}; name one with --member "
            f"({_member_names([members[i] for i in fitting] or members)})"
        )
    folded = wanted.casefold()
    for position, member in enumerate(members):
        spellings = (member.name.casefold(), member.shown_name.casefold())
        if wanted == member.fastcs_name or folded in spellings:
            return position
    raise SelectionError(
        f"{node.name_template!r} has no member {wanted!r} "
        f"(members: {_member_names(members)})"
    )


def _member_names(members: Sequence[SymbolMember]) -> str:
    return ", ".join(repr(m.shown_name) for m in members) or "none"


def set_units(
    terminal: TerminalType,
    symbol: str,
    member: str | None = None,
    *,
    scale: float | None = None,
    offset: float | None = None,
    unit: str | None = None,
    precision: int | None = None,
    reset: bool = False,
) -> TerminalType:
    """A copy whose member serves its value with these overrides of what its
    `dscale` gives (the others kept; `reset` drops all four first)."""
    changed = terminal.model_copy(deep=True)
    node = changed.symbol_nodes[find_symbol(changed, symbol)]
    position = find_member(node, member)
    target = node.members[position]
    data = dict(target)  # the fields as they are (a dump would serialise)
    if reset:
        data.update(dict.fromkeys(UNIT_CHOICES))
    wanted = {"scale": scale, "offset": offset, "unit": unit, "precision": precision}
    data.update({key: value for key, value in wanted.items() if value is not None})
    try:
        updated = SymbolMember.model_validate(data)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise SelectionError(f"{where}: {first['msg']}") from None
    node.members[position] = updated
    return _checked(changed)


def set_severity(
    terminal: TerminalType,
    symbol: str,
    member: str | None,
    severity: SeverityName | None,
) -> TerminalType:
    """A copy whose member raises `severity` while set (None: what its name
    implies again)."""
    changed = terminal.model_copy(deep=True)
    node = changed.symbol_nodes[find_symbol(changed, symbol)]
    node.members[find_member(node, member, status=True)].severity = severity
    return _checked(changed)
