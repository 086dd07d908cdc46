"""ESI device -> `TerminalType`: symbols from PDOs, groups, CoE, oversampling.

Per-channel PDOs that look the same (same channel template, same entry
layout, same PDO groups) collapse into one symbol node with a `{channel}`
template. The default PDO group starts selected; a terminal without groups
starts with every symbol selected. CoE objects start unselected: every
selected object costs mailbox traffic on the bus, so exposing one is an
engineer's decision.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import PurePath

from pydantic import ValidationError

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.model import (
    EsiCoeObject,
    EsiCoeSubItem,
    EsiDevice,
    EsiEntry,
    EsiEnumItem,
    EsiPdo,
)
from fastcs_ethercat.terminals.checks import check_terminal
from fastcs_ethercat.terminals.model import (
    CoeEnumItem,
    CoeObject,
    CoeSubItem,
    Identity,
    Oversampling,
    PdoGroup,
    SymbolMember,
    SymbolNode,
    TerminalType,
    coe_address,
)
from fastcs_ethercat.terminals.names import CHANNEL, snake_name, take_unique, templatize

COMMUNICATION_OBJECTS = range(0x1400, 0x1D00)
"""PDO parameters, mappings, assignments and SM settings: TwinCAT's business."""
PROCESS_DATA_OBJECTS = range(0x6000, 0x8000)
"""Inputs and outputs: read through the process image, not over the mailbox."""


def terminal_from_esi(device: EsiDevice) -> TerminalType:
    """The terminal description of one ESI device, with default selections;
    `UserError` naming the device when the ESI says what no terminal file
    can hold (a channel 300, a factor of 1 000: ranges of `terminals.model`)."""
    try:
        return _terminal_from_esi(device)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        value = first.get("input")
        shown = f" (got {value!r})" if isinstance(value, int | float | str) else ""
        problem = f"{where}: {first['msg']}{shown}" if where else first["msg"]
    except ValueError as error:  # check_terminal: a rule between fields broken
        problem = str(error)
    raise UserError(
        f"device {device.type_name}: no terminal file can describe it: {problem}",
        path=device.source,
    )


def _terminal_from_esi(device: EsiDevice) -> TerminalType:
    groups_of_pdo = _groups_of_pdos(device)
    clusters = _clusters(device.pdos, groups_of_pdo)
    over = device.oversampling
    templated = over is not None and over.origin == "pdo_attributes"
    oversampled = set(over.pdo_indices) if over is not None and templated else set()
    nodes = _symbol_nodes(clusters, oversampled)
    pdo_groups = _pdo_groups(device, nodes)
    selected_group = next((g.name for g in pdo_groups if g.is_default), None)
    in_default = next((set(g.symbol_indices) for g in pdo_groups if g.is_default), None)
    for position, node in enumerate(nodes):
        node.selected = in_default is None or position in in_default
    terminal = TerminalType(
        identity=Identity(
            vendor_id=device.vendor_id,
            product_code=device.product_code,
            revision_number=device.revision,
        ),
        description=device.description,
        group_type=device.group_type or None,
        esi_file=esi_file_name(device.source),
        pdo_groups=pdo_groups,
        selected_pdo_group=selected_group,
        oversampling=_oversampling(device, pdo_groups),
        symbol_nodes=nodes,
        coe_objects=_coe_objects(device.coe_objects.values()),
    )
    check_terminal(device.type_name, terminal)
    return terminal


def esi_file_name(source: str) -> str:
    """The file name of an ESI source (`dir/x.xml`, `zip!dir/x.xml` -> x.xml)."""
    return PurePath(source.rsplit("!", 1)[-1].replace("\\", "/")).name


def _groups_of_pdos(device: EsiDevice) -> dict[int, frozenset[str]]:
    found: dict[int, set[str]] = {}
    for group in device.pdo_groups:
        for index in group.pdo_indices:
            found.setdefault(index, set()).add(group.name)
    return {index: frozenset(names) for index, names in found.items()}


@dataclass
class _Cluster:
    """PDOs that become one symbol node (one per channel, or a single PDO)."""

    template: str | None
    pdos: list[EsiPdo]

    @property
    def channels(self) -> list[int]:
        return [p.channel for p in self.pdos if p.channel is not None]


def _layout(pdo: EsiPdo) -> tuple[object, ...]:
    """What must match for two channels' PDOs to share one node."""
    return (
        pdo.direction,
        pdo.channel_template,
        pdo.is_oversampling,
        tuple((e.is_padding, e.bit_len, e.data_type, e.dscale) for e in pdo.entries),
    )


def _clusters(
    pdos: Sequence[EsiPdo], groups_of_pdo: dict[int, frozenset[str]]
) -> list[_Cluster]:
    """Collapse per-channel PDOs; everything else is a cluster of its own."""
    clusters: list[_Cluster] = []
    open_by_key: dict[tuple[object, ...], list[_Cluster]] = {}
    for pdo in pdos:
        if pdo.channel is None or pdo.channel_template is None:
            clusters.append(_Cluster(template=None, pdos=[pdo]))
            continue
        key = (_layout(pdo), groups_of_pdo.get(pdo.index, frozenset()))
        candidates = open_by_key.setdefault(key, [])
        home = next(
            (
                c
                for c in candidates
                if pdo.channel not in c.channels and _member_names([*c.pdos, pdo])
            ),
            None,
        )
        if home is None:
            home = _Cluster(template=_unescape(pdo.channel_template), pdos=[])
            candidates.append(home)
            clusters.append(home)
        home.pdos.append(pdo)
    for cluster in clusters:
        cluster.pdos.sort(key=lambda p: p.channel or 0)
    return clusters


def _unescape(template: str) -> str:
    """The ESI parser's `str.format` template -> our plain `{channel}` text."""
    return template.format(channel=CHANNEL)


def _member_names(pdos: Sequence[EsiPdo]) -> list[str] | None:
    """Entry names shared by all channels (templated where they differ).

    None when the channels' entry names do not line up.
    """
    names: list[str] = []
    for position in range(len(pdos[0].entries)):
        raw = [p.entries[position].name for p in pdos]
        if len(set(raw)) == 1:
            names.append(raw[0])
            continue
        templated = {templatize(p.entries[position].name, p.channel or 0) for p in pdos}
        if len(templated) != 1:
            return None
        names.append(templated.pop())
    return names


def _symbol_nodes(clusters: list[_Cluster], oversampled: set[int]) -> list[SymbolNode]:
    nodes: list[SymbolNode] = []
    taken: set[str] = set()
    for cluster in clusters:
        node = _symbol_node(cluster, oversampled)
        node.fastcs_name = take_unique(
            node.fastcs_name, taken, f"{node.pdo_indices[0]:04x}"
        )
        nodes.append(node)
    return nodes


def _symbol_node(cluster: _Cluster, oversampled: set[int]) -> SymbolNode:
    first = cluster.pdos[0]
    name = cluster.template or first.name
    entry_names = _member_names(cluster.pdos) if cluster.template else None
    if entry_names is None:
        entry_names = [e.name for e in first.entries]
    samples = first.index in oversampled
    if samples:
        name = f"{name} 0"
    members = _members(cluster.pdos, entry_names)
    bit_size = sum(e.bit_len for e in first.entries)
    return SymbolNode(
        name_template=name,
        fastcs_name=snake_name(name),
        selected=True,
        channels=cluster.channels if cluster.template else [],
        pdo_indices=[p.index for p in cluster.pdos],
        direction="input" if first.direction == "tx" else "output",
        access="ro" if first.direction == "tx" else "rw",
        type_name=_symbol_type(name, first.entries, samples),
        bit_size=max(bit_size, 1),
        oversampled=samples,
        members=members,
    )


def _symbol_type(name: str, entries: Sequence[EsiEntry], samples: bool) -> str:
    """TwinCAT's type name for the symbol of a PDO (see the model docstring)."""
    if samples:
        return f"{name}_TYPE_ARR"
    if len(entries) == 1 and "__" not in entries[0].name:
        return twincat_type(entries[0])
    return f"{name}_TYPE"


def twincat_type(entry: EsiEntry) -> str:
    """The TwinCAT type of a PDO entry: a 1-bit BOOL is a BIT in the I/O tree."""
    data_type = entry.data_type
    if data_type in (None, "BOOL", "BIT") and entry.bit_len == 1:
        return "BIT"
    if data_type is None or data_type == "BOOL":
        return f"BIT{entry.bit_len}"
    return data_type


def _members(pdos: Sequence[EsiPdo], names: list[str]) -> list[SymbolMember]:
    members: list[SymbolMember] = []
    taken: set[str] = set()
    offset = 0
    for position, entry in enumerate(pdos[0].entries):
        start = offset
        offset += entry.bit_len
        if entry.is_padding:
            continue
        fastcs = take_unique(snake_name(names[position]), taken, str(position))
        members.append(
            SymbolMember(
                name=names[position],
                fastcs_name=fastcs,
                type_name=twincat_type(entry),
                bit_offset=start,
                bit_size=entry.bit_len,
                coe=[
                    coe_address(p.entries[position].index, p.entries[position].subindex)
                    for p in pdos
                ],
                comment=entry.comment,
                dscale=entry.dscale,
            )
        )
    return members


def _pdo_groups(device: EsiDevice, nodes: list[SymbolNode]) -> list[PdoGroup]:
    factors = device.oversampling.group_factors if device.oversampling else {}
    groups: list[PdoGroup] = []
    for group in device.pdo_groups:
        members = set(group.pdo_indices)
        groups.append(
            PdoGroup(
                name=group.name,
                is_default=group.is_default,
                pdo_indices=list(group.pdo_indices),
                symbol_indices=[
                    position
                    for position, node in enumerate(nodes)
                    if set(node.pdo_indices) <= members
                ],
                oversampling_factor=factors.get(group.name),
            )
        )
    if groups and not any(g.is_default for g in groups):
        groups[0].is_default = True
    return groups


def _oversampling(device: EsiDevice, groups: list[PdoGroup]) -> Oversampling | None:
    over = device.oversampling
    if over is None or not over.factors:
        return None
    default = over.default_factor
    if default is None or default not in over.factors:
        group_default = next(
            (g.oversampling_factor for g in groups if g.is_default), None
        )
        default = group_default if group_default in over.factors else over.factors[0]
    assert default is not None
    return Oversampling(
        factors=list(over.factors),
        default_factor=default,
        selected_factor=default,
        pdo_indices=list(over.pdo_indices),
        by_group=over.origin == "pdo_groups",
    )


def _coe_objects(objects: Iterable[EsiCoeObject]) -> list[CoeObject]:
    result: list[CoeObject] = []
    for obj in sorted(objects, key=lambda o: o.index):
        if obj.index in COMMUNICATION_OBJECTS or obj.index in PROCESS_DATA_OBJECTS:
            continue
        result.append(_coe_object(obj))
    return result


def _coe_object(obj: EsiCoeObject) -> CoeObject:
    return CoeObject(
        index=obj.index,
        name=obj.name,
        fastcs_name=f"{snake_name(obj.name)}_{obj.index:04x}",
        selected=False,
        type_name=obj.type_name,
        bit_size=obj.bit_size,
        access=obj.access,
        default_data=obj.default_data,
        enum=_enum(obj.enum_items),
        sub_items=_sub_items(obj.sub_items),
    )


def _sub_items(items: Sequence[EsiCoeSubItem]) -> list[CoeSubItem]:
    kept = [s for s in items if s.subindex != 0] if len(items) > 1 else list(items)
    result: list[CoeSubItem] = []
    taken: set[str] = set()
    for sub in kept:
        fastcs = take_unique(snake_name(sub.name), taken, f"{sub.subindex:02x}")
        result.append(
            CoeSubItem(
                subindex=sub.subindex,
                name=sub.name,
                fastcs_name=fastcs,
                type_name=sub.type_name,
                bit_size=sub.bit_size,
                bit_offset=sub.bit_offset,
                access=sub.access,
                default_data=sub.default_data,
                default_value=sub.default_value,
                min_value=sub.min_value,
                max_value=sub.max_value,
                unit=sub.unit,
                enum=_enum(sub.enum_items),
            )
        )
    return result


def _enum(items: Sequence[EsiEnumItem]) -> list[CoeEnumItem]:
    return [CoeEnumItem(value=i.value, text=i.text) for i in items]
