"""Live symbol table + terminal YAML -> the points each terminal serves.

The live table is the only truth about which PDOs exist (dynamic PDOs), their
addresses, array lengths (oversampling) and member layouts (data-type table);
the YAML adds names, selection and CoE objects. A terminal whose revision has
no YAML is served from the nearest revision of its product code, matched to
the live table by name: what the live table lacks is dropped, in one warning
naming both revisions. Only a product code without any YAML gets a generic
plan: every live symbol, read-only.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final, TypedDict, Unpack

from fastcs_ethercat.ads.client import SymbolTables
from fastcs_ethercat.ads.constants import IndexGroup
from fastcs_ethercat.ads.datatypes import AdsDataTypeEntry, MemberLayout, walk_members
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.symbols import AdsSymbolEntry
from fastcs_ethercat.ads.values import parse_type
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.plan import (
    CoePoint,
    MasterPlan,
    Point,
    PointKind,
    SlaveInfo,
    Source,
    TerminalPlan,
)
from fastcs_ethercat.logs import first_names
from fastcs_ethercat.terminals.meaning import (
    SEVERITY_LEVELS,
    Scaling,
    coe_unit,
    describe,
    severity_of_name,
)
from fastcs_ethercat.terminals.model import CoeObject, CoeSubItem, TerminalType
from fastcs_ethercat.terminals.names import snake_name, take_unique
from fastcs_ethercat.terminals.registry import RegistryMatch, TerminalRegistry
from fastcs_ethercat.terminals.symbols import ExpandedSymbol, expanded_symbols

BIT_GROUPS = frozenset(
    {IndexGroup.IO_IMAGE_RW_INPUT_BITS, IndexGroup.IO_IMAGE_RW_OUTPUT_BITS}
)
"""Bit-addressed image groups: offset in bits, one byte (0/1) per bit read."""
RUNTIME_ATTRIBUTES = {
    "WcState.WcState": "wc_state",
    "WcState.InputToggle": "input_toggle",
}
"""TwinCAT's per-terminal runtime symbols (not in the ESI) and their names."""

Types = Mapping[str, AdsDataTypeEntry]
NUMBER_KINDS = frozenset({PointKind.SCALAR, PointKind.ARRAY})
"""Points whose value can be served in engineering units (not status bits)."""


def snake_case(text: str) -> str:
    """A stable attribute name: `Frm0WcState` -> `frm0_wc_state`."""
    return snake_name(text, split_camel=True)


def group_symbols(symbols: Iterable[AdsSymbolEntry]) -> dict[str, list[AdsSymbolEntry]]:
    """Symbols by the part of their name before the first dot (`Term 5 (EL3104)`)."""
    groups: dict[str, list[AdsSymbolEntry]] = defaultdict(list)
    for entry in symbols:
        prefix, dot, _ = entry.name.partition(".")
        if dot:
            groups[prefix].append(entry)
    return dict(groups)


@dataclass(frozen=True, slots=True)
class _Member:
    """A leaf of a live symbol, addressed for a sum read."""

    path: str  # "Status.Underrange"; "" for the symbol itself
    type_name: str
    kind: PointKind
    byte_offset: int  # from the symbol start: the bytes to read
    byte_size: int
    bit_offset: int = 0
    bit_size: int = 0
    length: int = 1


def symbol_members(entry: AdsSymbolEntry, types: Types) -> list[_Member]:
    """The leaves of a live symbol from the data-type table (empty if unknown)."""
    if entry.index_group in BIT_GROUPS:
        return [_Member("", "BIT", PointKind.BIT, 0, 1, 0, 1)]
    data_type = types.get(entry.type_name)
    if data_type is None:
        leaf = _leaf("", entry.type_name, 0, entry.size)
        return [leaf] if leaf else []
    members = (_member(layout) for layout in walk_members(data_type, types))
    return [member for member in members if member is not None]


def _member(layout: MemberLayout) -> _Member | None:
    """A leaf of the codec's type walk, addressed for a sum read."""
    if layout.bit_size:
        kind = PointKind.BIT if layout.bit_size == 1 else PointKind.BITS
        return _Member(
            layout.path,
            layout.type_name,
            kind,
            layout.offset,
            layout.size,
            layout.bit_offset,
            layout.bit_size,
        )
    if layout.dimensions:  # a named array type: oversampling
        length = math.prod(d.element_count for d in layout.dimensions)
        try:
            element = parse_type(layout.type_name)
        except AdsCodecError:
            return None
        return _Member(
            layout.path,
            element.name,
            PointKind.ARRAY,
            layout.offset,
            element.size * length,
            length=length,
        )
    return _leaf(layout.path, layout.type_name, layout.offset, layout.size)


def _leaf(path: str, type_name: str, offset: int, size: int) -> _Member | None:
    try:
        parsed = parse_type(type_name)
    except AdsCodecError:
        return None
    if parsed.kind == "array" and parsed.element is not None:
        return _Member(
            path,
            parsed.element.name,
            PointKind.ARRAY,
            offset,
            parsed.size,
            length=parsed.size // max(parsed.element.size, 1),
        )
    return _Member(path, parsed.name, PointKind.SCALAR, offset, size or parsed.size)


class _Meaning(TypedDict, total=False):
    """What a point means beyond where its bytes are: `Point`'s fields of
    the same names (their defaults where not given)."""

    writable: bool
    description: str
    scaling: Scaling | None
    severity: int
    channel: int | None
    entry_name: str


def _point(
    master: str,
    entry: AdsSymbolEntry,
    member: _Member,
    attribute: str,
    **meaning: Unpack[_Meaning],
) -> Point:
    """The point of `member` of the live symbol `entry`."""
    symbol = f"{entry.name}.{member.path}" if member.path else entry.name
    return Point(
        key=f"{master}/{symbol}",
        symbol=symbol,
        attribute=attribute,
        type_name=member.type_name,
        kind=member.kind,
        index_group=entry.index_group,
        index_offset=entry.index_offset + member.byte_offset,
        byte_size=member.byte_size,
        bit_offset=member.bit_offset,
        bit_size=member.bit_size,
        length=member.length,
        **meaning,
        source=Source(entry.name, member.byte_offset, entry.type_name, entry.size),
    )


@dataclass(frozen=True, slots=True)
class _PointShape:
    """A point as every terminal of one type and live layout has it: all of
    it but where the terminal's symbol is (`_point` adds that)."""

    rest: str
    """The live symbol's name after the terminal's (`AI Standard Channel 1`)."""
    member: _Member
    attribute: str
    meaning: _Meaning


def _live_point(
    master: str, entry: AdsSymbolEntry, member: _Member, attribute: str, kind: str
) -> Point:
    """A point of a symbol no YAML describes (master, unknown terminal)."""
    rest = entry.name.partition(".")[2] or entry.name
    meaning = _live_meaning(rest, member, kind)
    return _point(master, entry, member, attribute, **meaning)


def _live_meaning(rest: str, member: _Member, kind: str) -> _Meaning:
    """A live symbol's member no YAML describes (runtime, master, unknown
    terminal): its DESC and severity from its names (read-only, so nothing
    here is an output)."""
    severity = severity_of_name(member.path or rest)
    return _Meaning(
        description=describe(kind or None, rest, member.path or None),
        severity=SEVERITY_LEVELS[severity],
    )


def _fallback_members(symbol: ExpandedSymbol) -> list[_Member]:
    """Members from the YAML's bit offsets when the live type is not listed."""
    found: list[_Member] = []
    for member in symbol.members:
        path = ".".join(member.path)
        if member.bit_size % 8 or member.bit_offset % 8:
            start = member.bit_offset // 8
            size = (member.bit_offset % 8 + member.bit_size + 7) // 8
            kind = PointKind.BIT if member.bit_size == 1 else PointKind.BITS
            found.append(
                _Member(
                    path,
                    member.type_name,
                    kind,
                    start,
                    size,
                    member.bit_offset % 8,
                    member.bit_size,
                )
            )
        else:
            leaf = _leaf(path, member.type_name, member.bit_offset // 8, 0)
            if leaf:
                found.append(leaf)
    return found


# -- per terminal -------------------------------------------------------------


def detect_active_group(
    terminal: TerminalType,
    names_by_group: Mapping[str, frozenset[str]],
    live: Iterable[str],
) -> str | None:
    """The PDO group whose symbols (`names_by_group`) the live table holds
    (most of them)."""
    names = set(live)
    best: tuple[int, int, str] | None = None
    wanted = terminal.active_group
    for group in terminal.pdo_groups:
        score = len(names_by_group[group.name] & names)
        if not score:
            continue
        rank = (
            score,
            int(wanted is not None and group.name == wanted.name),
            group.name,
        )
        if best is None or rank[:2] > best[:2]:
            best = rank
    return None if best is None else best[2]


def chosen_symbols(terminal: TerminalType, active: str | None) -> list[ExpandedSymbol]:
    """The symbols to serve, per channel, in the order the terminal's
    `served_nodes` gives (the one rule of what a terminal serves)."""
    return expanded_symbols(terminal, nodes=terminal.served_nodes(active))


Layout = tuple[str, int, bool] | None
"""What the members of a live symbol depend on (`symbol_members`): its type,
its size, whether it is bit-addressed; None: not on the target."""


_ShapeKey = tuple[str | None, tuple[Layout, ...], tuple[Layout, ...]]
"""The running group, the layouts of the served symbols, of the runtime ones."""


def _layout(entry: AdsSymbolEntry | None) -> Layout:
    if entry is None:
        return None
    return (entry.type_name, entry.size, entry.index_group in BIT_GROUPS)


class TypeView:
    """What every terminal of one type shares: its symbol names (all, and per
    PDO group), the symbols it serves per running group, its points per live
    layout and its CoE points. Only the served nodes are expanded with their
    members: a terminal with many PDO groups (ELM3704: 5 540 members, 34
    served) serves a few."""

    def __init__(self, terminal: TerminalType, type_name: str, types: Types) -> None:
        self.terminal = terminal
        self.type_name = type_name
        self.types = types
        by_node = [node.names() for node in terminal.symbol_nodes]
        self.symbol_names = frozenset(name for names in by_node for name in names)
        """Every symbol the YAML describes, per channel (after the terminal's name)."""
        self.names_by_group = {
            group.name: frozenset(
                name for index in group.symbol_indices for name in by_node[index]
            )
            for group in terminal.pdo_groups
        }
        self.coe = tuple(coe_points(terminal))
        self._served: dict[str | None, list[ExpandedSymbol]] = {}
        self._shapes: dict[_ShapeKey, tuple[list[_PointShape], list[str]]] = {}

    def served(self, active: str | None) -> list[ExpandedSymbol]:
        """`chosen_symbols(terminal, active)` (shared: do not modify)."""
        found = self._served.get(active)
        if found is None:
            found = self._served[active] = chosen_symbols(self.terminal, active)
        return found

    def shapes(
        self, active: str | None, live: Mapping[str, AdsSymbolEntry]
    ) -> tuple[list[_PointShape], list[str]]:
        """(the points, the served symbols `live` lacks) of a terminal of this
        type running `active` with the live symbols `live` (by their name
        after the terminal's); the same for every terminal whose live symbols
        have the same layouts (shared: do not modify)."""
        served = self.served(active)
        key: _ShapeKey = (
            active,
            tuple(_layout(live.get(symbol.name)) for symbol in served),
            tuple(_layout(live.get(rest)) for rest in RUNTIME_ATTRIBUTES),
        )
        found = self._shapes.get(key)
        if found is None:
            found = self._shapes[key] = self._shapes_of(served, live)
        return found

    def _shapes_of(
        self, served: list[ExpandedSymbol], live: Mapping[str, AdsSymbolEntry]
    ) -> tuple[list[_PointShape], list[str]]:
        names: set[str] = set()
        shapes: list[_PointShape] = []
        dropped: list[str] = []
        for symbol in served:
            entry = live.get(symbol.name)
            if entry is None:
                dropped.append(symbol.name)
                continue
            members = symbol_members(entry, self.types) or _fallback_members(symbol)
            shapes += _yaml_shapes(symbol, members, names, self.type_name)
        for rest, attribute in RUNTIME_ATTRIBUTES.items():
            entry = live.get(rest)
            if entry is not None:
                for member in symbol_members(entry, self.types):
                    attribute = take_unique(attribute, names)
                    meaning = _live_meaning(rest, member, self.type_name)
                    shapes.append(_PointShape(rest, member, attribute, meaning))
        return shapes, dropped


class Resolver:
    """Resolves slaves against one master's live tables. What the terminals
    of one type share (`TypeView`) is worked out once per type, so a rack of
    a few types repeated costs little more than its types; made anew for
    every discovery, nothing outlives the tables it was made for."""

    def __init__(self, types: Types, registry: TerminalRegistry) -> None:
        self.types = types
        self.registry = registry
        self._views: dict[tuple[str, int], TypeView] = {}

    def _view(self, match: RegistryMatch) -> TypeView:
        key = (match.type_name, id(match.terminal))
        found = self._views.get(key)
        if found is None:  # the view keeps the terminal: its id stays its own
            found = TypeView(match.terminal, match.type_name, self.types)
            self._views[key] = found
        return found

    def terminal(
        self, master: str, slave: SlaveInfo, entries: Sequence[AdsSymbolEntry]
    ) -> TerminalPlan:
        """One slave's plan: matched YAML (or generic) and its points."""
        identity = slave.identity
        match = self.registry.lookup(
            identity.product_code, identity.revision, identity.vendor_id
        )
        if match is None:
            plan = TerminalPlan(slave=slave, terminal_type=None)
            plan.points = generic_points(master, entries, self.types, slave.type_name)
            if entries:
                plan.warnings.append(
                    f"{slave.name}: no terminal YAML for product code "
                    f"0x{identity.product_code:08x} revision "
                    f"0x{identity.revision:08x}; "
                    f"serving its {len(entries)} live symbols read-only"
                )
            return plan
        terminal = match.terminal
        plan = TerminalPlan(
            slave=slave, terminal_type=match.type_name, exact_revision=match.exact
        )
        prefix = f"{slave.name}."
        live = {e.name[len(prefix) :]: e for e in entries if e.name.startswith(prefix)}
        view = self._view(match)
        plan.active_group = detect_active_group(terminal, view.names_by_group, live)
        plan.oversampling = oversampling_factor(terminal, live)
        wanted = terminal.active_group
        if wanted is not None and plan.active_group not in (None, wanted.name):
            plan.warnings.append(
                f"{slave.name}: the PLC runs PDO group {plan.active_group!r}, the "
                f"YAML selects {wanted.name!r}; serving {plan.active_group!r}"
            )
        shapes, dropped = view.shapes(plan.active_group, live)
        plan.points = [
            _point(
                master, live[shape.rest], shape.member, shape.attribute, **shape.meaning
            )
            for shape in shapes
        ]
        if not match.exact or dropped:
            unknown = sum(
                1
                for rest in live
                if rest not in view.symbol_names and rest not in RUNTIME_ATTRIBUTES
            )
            plan.warnings.append(_match_warning(slave, match, dropped, unknown))
        plan.coe = list(view.coe)
        return plan


def _match_warning(
    slave: SlaveInfo, match: RegistryMatch, dropped: list[str], unknown: int
) -> str:
    """One line: which YAML serves the slave, what the live table lacks and
    how many live symbols the YAML does not describe."""
    text = f"{slave.name}: "
    if not match.exact:
        text += (
            f"revision 0x{slave.identity.revision:08x} has no YAML; served from "
            f"{match.type_name} revision 0x{match.revision:08x}"
        )
    if dropped:
        shown = first_names([repr(name) for name in dropped])
        text += "; " if not match.exact else ""
        text += f"{len(dropped)} selected symbols not on the target, dropped: {shown}"
    if unknown:
        text += f"; {unknown} live symbols it does not describe, not served"
    return text


def oversampling_factor(
    terminal: TerminalType, live: Mapping[str, AdsSymbolEntry]
) -> int | None:
    """Samples per cycle as the live table has them: an oversampled symbol's
    live size over one sample's (None: not an oversampling terminal, or the
    factor follows the PDO group)."""
    oversampling = terminal.oversampling
    if oversampling is None or oversampling.by_group:
        return None
    for node in terminal.symbol_nodes:
        if not node.oversampled:
            continue
        for name in node.names():
            entry = live.get(name)
            if entry is not None:
                return max(1, 8 * entry.size // node.bit_size)
    return None


def _yaml_shapes(
    symbol: ExpandedSymbol, members: list[_Member], names: set[str], type_name: str
) -> list[_PointShape]:
    """The points of the live `members` of a symbol the YAML describes;
    `names` holds the terminal's attributes so far (each is made unique)."""
    by_path = {".".join(m.path): m for m in symbol.members}
    by_last = {m.path[-1]: m for m in symbol.members}
    if len(symbol.members) == 1:  # a one-entry PDO is a symbol of the entry's type
        by_path[""] = symbol.members[0]
    writable = symbol.direction == "output"
    shapes: list[_PointShape] = []
    for member in members:
        yaml_member = by_path.get(member.path) or by_last.get(
            member.path.rpartition(".")[2]
        )
        if not member.path:
            attribute = symbol.fastcs_name
        elif yaml_member is not None and len(symbol.members) > 1:
            attribute = f"{symbol.fastcs_name}_{yaml_member.fastcs_name}"
        elif yaml_member is not None:
            attribute = symbol.fastcs_name
        else:
            attribute = f"{symbol.fastcs_name}_{snake_case(member.path)}"
        meaning = _Meaning(
            writable=writable,
            description=describe(
                type_name,
                symbol.name,
                yaml_member.name if yaml_member else member.path or None,
            ),
            scaling=(
                yaml_member.scaling
                if yaml_member and member.kind in NUMBER_KINDS
                else None
            ),
            severity=SEVERITY_LEVELS[yaml_member.severity] if yaml_member else 0,
            channel=symbol.channel,
            entry_name=member.path or symbol.entry_name,
        )
        shapes.append(
            _PointShape(symbol.name, member, take_unique(attribute, names), meaning)
        )
    return shapes


def generic_points(
    master: str, entries: Sequence[AdsSymbolEntry], types: Types, kind: str = ""
) -> list[Point]:
    """Every live symbol of an unknown terminal, read-only, in name order."""

    def name(rest: str, member: _Member) -> str:
        base = RUNTIME_ATTRIBUTES.get(rest) or snake_case(rest)
        return f"{base}_{snake_case(member.path)}" if member.path else base

    return _live_points(master, entries, types, name, kind)


def _live_points(
    master: str,
    entries: Sequence[AdsSymbolEntry],
    types: Types,
    name: Callable[[str, _Member], str],
    kind: str = "",
) -> list[Point]:
    """Every member of `entries`, read-only, in name order; `name(rest of
    the symbol's name, member)` names each attribute (made unique); `kind`
    (the slave's type) starts their descriptions."""
    names: set[str] = set()
    points: list[Point] = []
    for entry in sorted(entries, key=lambda e: e.name):
        rest = entry.name.partition(".")[2]
        for member in symbol_members(entry, types):
            attribute = take_unique(name(rest, member), names)
            points.append(_live_point(master, entry, member, attribute, kind))
    return points


def coe_points(terminal: TerminalType) -> list[CoePoint]:
    """The YAML's selected CoE objects, one point per sub-item."""
    points: list[CoePoint] = []
    for obj in terminal.served_coe_objects():
        points.extend(coe_object_points(obj))
    return points


def coe_object_points(obj: CoeObject) -> list[CoePoint]:
    """A CoE object's selected sub-items (or the object itself when it has none)."""
    if not obj.sub_items:
        return [_coe_point(obj, obj, 0, obj.fastcs_name, obj.name)]
    return [
        _coe_point(
            obj,
            sub,
            sub.subindex,
            f"{obj.fastcs_name}_{sub.fastcs_name}",
            f"{obj.name}: {sub.name}",
        )
        for sub in obj.sub_items
        if sub.selected
    ]


def _coe_point(
    obj: CoeObject,
    item: CoeObject | CoeSubItem,
    subindex: int,
    attribute: str,
    description: str,
) -> CoePoint:
    """One point of `obj`: a sub-item, or the object itself; a sub-item
    without its own access or unit has the object's."""
    return CoePoint(
        attribute=attribute,
        index=obj.index,
        subindex=subindex,
        type_name=item.type_name,
        bit_size=item.bit_size,
        writable=obj.access_of(item) in ("rw", "wo"),
        description=description,
        default=item.default_value or item.default_data or "",
        enum_texts=tuple((e.value, e.text) for e in item.enum),
        units=coe_unit(item.unit or obj.unit),
        name=item.name,
        object_name=obj.name,
    )


# -- per master ---------------------------------------------------------------


MASTER_NODES: Final = ("Inputs", "Outputs")
"""The master's own process data (frame and working-counter states, slave
count, device state and control)."""


def master_symbols(
    master: str,
    symbols: Sequence[AdsSymbolEntry],
    groups: Mapping[str, list[AdsSymbolEntry]],
    slave_names: Collection[str],
) -> list[AdsSymbolEntry]:
    """The master's own symbols on its device port: named under the device
    (`Device 1 (EtherCAT).Inputs`), as a real rack's symbol dump shows them,
    or bare (`Inputs`, or `Inputs.Frm0State` one by one), as the facts
    file's section 7 has them: a target serving those gets its master points
    too. A terminal called `Inputs` keeps its own symbols."""
    found = list(groups.get(master, []))
    bare = [node for node in MASTER_NODES if node not in slave_names]
    if bare:
        found += [entry for entry in symbols if entry.name in bare]
        for node in bare:
            found += groups.get(node, [])
    return found


def master_points(
    master: str, entries: Sequence[AdsSymbolEntry], types: Types
) -> list[Point]:
    """The master's own `Inputs` / `Outputs` members, read-only."""
    return _live_points(
        master, entries, types, lambda rest, member: snake_case(member.path or rest)
    )


def resolve_master(
    master: MasterPlan,
    slaves: Sequence[SlaveInfo],
    tables: SymbolTables,
    registry: TerminalRegistry,
    config: IocConfig,
) -> list[str]:
    """Fill `master` with a plan per slave; return the warnings."""
    types = {t.name: t for t in tables.data_types}
    groups = group_symbols(tables.symbols)
    own = master_symbols(
        master.name, tables.symbols, groups, {slave.name for slave in slaves}
    )
    master.master_points = master_points(master.name, own, types)
    warnings: list[str] = []
    resolver = Resolver(types, registry)
    for slave in slaves:
        plan = resolver.terminal(master.name, slave, groups.get(slave.name, []))
        override = config.terminals.get(slave.name)
        if override is not None:
            plan.poll_rate_hz = override.poll_rate_hz
        warnings.extend(plan.warnings)
        master.terminals.append(plan)
    return warnings
