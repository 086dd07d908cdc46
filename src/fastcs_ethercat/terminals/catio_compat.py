"""Read catio-terminals' single-file layout (`terminal_types:` of many types).

catio stores a structure's fields as extra "dotted" symbol nodes
(`AI Standard Channel {channel}.Value`) next to the structure's own node,
counts channels (`channels: 4`, optional `channel_indices`), says
`Read-only`/`Read/Write` instead of a direction, records no PDO indices or
CoE addresses, and keeps only selected CoE objects. This module validates
that layout (unknown keys are errors, as in ours) and converts each type to
our `TerminalType`: dotted nodes become members of their structure, group
`symbol_indices` are renumbered, unknown PDO indices and CoE addresses stay
empty. Writing always uses our layout.
"""

from __future__ import annotations

import re
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from fastcs_ethercat.terminals.checks import terminal_problems
from fastcs_ethercat.terminals.files import (
    CATIO_LAYOUT_KEY,
    located_error,
    validation_error,
)
from fastcs_ethercat.terminals.model import (
    CoeObject,
    CoeSubItem,
    Identity,
    PdoGroup,
    SymbolMember,
    SymbolNode,
    TerminalType,
)
from fastcs_ethercat.terminals.names import CHANNEL, snake_name, unique_name
from fastcs_ethercat.terminals.twincat_types import primitive_bit_size
from fastcs_ethercat.terminals.yaml_io import Loc, LocatedYaml

COMPOSITE_TYPES_KEY = "composite_types"
_FASTCS_OK = r"^[a-z][a-z0-9_]*(\{channel\}[a-z0-9_]*)*$"


class _Catio(BaseModel):
    model_config = ConfigDict(extra="forbid")


class CatioIdentity(_Catio):
    vendor_id: int
    product_code: int
    revision_number: int


class CatioSymbol(_Catio):
    name_template: str
    index_group: int | None = None
    type_name: str
    channels: int = 1
    channel_indices: list[int] = Field(default_factory=list)
    access: str | None = None
    fastcs_name: str | None = None
    tooltip: str | None = None
    selected: bool = True
    bit_offset: int = 0
    size: int | None = None
    ads_type: int | None = None


class CatioCoeSub(_Catio):
    subindex: int
    name: str
    type_name: str | None = None
    bit_size: int | None = None
    access: str | None = None
    default_data: str | None = None
    fastcs_name: str | None = None


class CatioCoe(_Catio):
    index: int
    name: str
    type_name: str
    bit_size: int
    access: str | None = None
    subindices: list[CatioCoeSub] = Field(default_factory=list)
    selected: bool = True
    """catio writes only selected objects, so everything read is selected."""
    fastcs_name: str | None = None


class CatioGroup(_Catio):
    name: str
    is_default: bool = False
    pdo_indices: list[int] = Field(default_factory=list)
    symbol_indices: list[int] = Field(default_factory=list)


class CatioTerminal(_Catio):
    description: str
    identity: CatioIdentity
    symbol_nodes: list[CatioSymbol] = Field(default_factory=list)
    coe_objects: list[CatioCoe] = Field(default_factory=list)
    group_type: str | None = None
    pdo_groups: list[CatioGroup] = Field(default_factory=list)
    selected_pdo_group: str | None = None


def read_catio_layout(located: LocatedYaml) -> dict[str, TerminalType]:
    """Every terminal type of a catio-terminals file, converted."""
    data = located.data
    assert isinstance(data, dict)
    for key in data:
        if key not in (CATIO_LAYOUT_KEY, COMPOSITE_TYPES_KEY):
            raise located_error(located, (key,), f"unknown key {key!r}", 1)
    types = data[CATIO_LAYOUT_KEY]
    if not isinstance(types, dict):
        raise located_error(
            located, (CATIO_LAYOUT_KEY,), "expected a mapping of terminal types", 1
        )
    sizes = _composite_sizes(data.get(COMPOSITE_TYPES_KEY))
    result: dict[str, TerminalType] = {}
    for name, body in types.items():
        loc: Loc = (CATIO_LAYOUT_KEY, name)
        if not isinstance(name, str):
            raise located_error(located, loc, "a terminal type name must be text", 1)
        try:
            catio = CatioTerminal.model_validate(body)
        except ValidationError as error:
            raise validation_error(located, loc, error) from None
        try:
            terminal = convert_terminal(catio, sizes)
        except ValidationError as error:
            raise located_error(
                located, loc, f"cannot convert: {error.errors()[0]['msg']}", 1
            ) from None
        problems = terminal_problems(terminal)
        if problems:
            first = problems[0]
            raise located_error(
                located, loc, f"after conversion: {first.message}", len(problems)
            )
        result[name] = terminal
    return result


def _composite_sizes(composites: Any) -> dict[str, int]:
    """Bit size per catio composite type (`size` is in bytes)."""
    if not isinstance(composites, dict):
        return {}
    sizes: dict[str, int] = {}
    for name, body in composites.items():
        if isinstance(body, dict) and isinstance(body.get("size"), int):
            sizes[str(name)] = body["size"] * 8
    return sizes


def _bit_size(type_name: str, sizes: dict[str, int]) -> int | None:
    return primitive_bit_size(type_name) or sizes.get(type_name)


def _parent_of(name: str, tops: list[str]) -> tuple[str, str] | None:
    """(structure, field) of a dotted catio node name, or None if not dotted."""
    for top in sorted(tops, key=len, reverse=True):
        if name.startswith(top + "."):
            return top, name[len(top) + 1 :]
    if "." not in name:
        return None
    parent, field = name.split(".", 1)
    return parent, field


def _channels(symbol: CatioSymbol) -> list[int]:
    if CHANNEL not in symbol.name_template:
        return []
    return symbol.channel_indices or list(range(1, symbol.channels + 1))


def _fastcs(name: str | None, fallback: str) -> str:
    if name and re.match(_FASTCS_OK, name):
        return name
    return snake_name(fallback)


def convert_terminal(catio: CatioTerminal, sizes: dict[str, int]) -> TerminalType:
    """catio's description of one type as our `TerminalType`."""
    tops = [s.name_template for s in catio.symbol_nodes if "." not in s.name_template]
    nodes: dict[str, SymbolNode] = {}
    flat_to_node: dict[int, str] = {}
    pending: dict[str, list[tuple[str, CatioSymbol]]] = {}
    for position, symbol in enumerate(catio.symbol_nodes):
        split = _parent_of(symbol.name_template, tops)
        parent = split[0] if split else symbol.name_template
        flat_to_node[position] = parent
        if split is None:
            nodes[parent] = _node(symbol, parent, sizes, own_type=True)
        else:
            pending.setdefault(parent, []).append((split[1], symbol))
    for parent, fields in pending.items():
        if parent not in nodes:
            nodes[parent] = _node(fields[0][1], parent, sizes, own_type=False)
        node = nodes[parent]
        node.members = _members(fields, sizes)
        end = max((m.bit_offset + m.bit_size for m in node.members), default=1)
        node.bit_size = max(node.bit_size, end)
        node.selected = node.selected or any(s.selected for _, s in fields)
    ordered = list(nodes)
    _unique_fastcs(nodes)
    groups = [
        PdoGroup(
            name=group.name,
            is_default=group.is_default,
            pdo_indices=group.pdo_indices,
            symbol_indices=sorted(
                {
                    ordered.index(flat_to_node[i])
                    for i in group.symbol_indices
                    if i in flat_to_node
                }
            ),
        )
        for group in catio.pdo_groups
    ]
    return TerminalType(
        identity=Identity(**catio.identity.model_dump()),
        description=catio.description,
        group_type=catio.group_type,
        pdo_groups=groups,
        selected_pdo_group=_selected_group(catio, groups),
        symbol_nodes=[nodes[name] for name in ordered],
        coe_objects=_coe_objects(catio.coe_objects),
    )


def _selected_group(catio: CatioTerminal, groups: list[PdoGroup]) -> str | None:
    """catio's choice, else its default group (older files may lack one)."""
    if not groups:
        return None
    if catio.selected_pdo_group is not None:
        return catio.selected_pdo_group
    default = next((g for g in groups if g.is_default), groups[0])
    return default.name


def _node(
    symbol: CatioSymbol, name: str, sizes: dict[str, int], *, own_type: bool
) -> SymbolNode:
    output = (symbol.access or "").lower().replace(" ", "") == "read/write"
    type_name = symbol.type_name if own_type else f"{name}_TYPE"
    return SymbolNode(
        name_template=name,
        fastcs_name=_fastcs(symbol.fastcs_name if own_type else None, name),
        selected=symbol.selected if own_type else False,
        channels=_channels(symbol),
        pdo_indices=[],
        direction="output" if output else "input",
        access="rw" if output else "ro",
        type_name=type_name,
        bit_size=(_bit_size(type_name, sizes) if own_type else None) or 1,
        members=[],
    )


def _members(
    fields: list[tuple[str, CatioSymbol]], sizes: dict[str, int]
) -> list[SymbolMember]:
    members: list[SymbolMember] = []
    taken: set[str] = set()
    for name, symbol in sorted(fields, key=lambda item: item[1].bit_offset):
        fastcs = unique_name(snake_name(name), taken, str(len(taken)))
        taken.add(fastcs)
        members.append(
            SymbolMember(
                name=name,
                fastcs_name=fastcs,
                type_name=symbol.type_name,
                bit_offset=symbol.bit_offset,
                bit_size=_bit_size(symbol.type_name, sizes) or 1,
                coe=[],
                comment=symbol.tooltip,
            )
        )
    return members


def _unique_fastcs(nodes: dict[str, SymbolNode]) -> None:
    taken: set[str] = set()
    for node in nodes.values():
        node.fastcs_name = unique_name(node.fastcs_name, taken, str(len(taken)))
        taken.add(node.fastcs_name)


def _access(text: str | None) -> Any:
    value = (text or "").lower()
    return value if value in ("ro", "rw", "wo") else None


def _coe_objects(objects: list[CatioCoe]) -> list[CoeObject]:
    result: list[CoeObject] = []
    taken: set[str] = set()
    for obj in objects:
        fastcs = unique_name(
            _fastcs(obj.fastcs_name, obj.name), taken, f"{obj.index:04x}"
        )
        taken.add(fastcs)
        sub_taken: set[str] = set()
        subs: list[CoeSubItem] = []
        for sub in obj.subindices:
            sub_fastcs = unique_name(
                _fastcs(sub.fastcs_name, sub.name), sub_taken, f"{sub.subindex:02x}"
            )
            sub_taken.add(sub_fastcs)
            subs.append(
                CoeSubItem(
                    subindex=sub.subindex,
                    name=sub.name,
                    fastcs_name=sub_fastcs,
                    type_name=sub.type_name or "",
                    bit_size=sub.bit_size or 0,
                    access=_access(sub.access),
                    default_data=sub.default_data,
                )
            )
        result.append(
            CoeObject(
                index=obj.index,
                name=obj.name,
                fastcs_name=fastcs,
                selected=obj.selected,
                type_name=obj.type_name,
                bit_size=obj.bit_size,
                access=_access(obj.access),
                sub_items=subs,
            )
        )
    return result


__all__ = ["CatioTerminal", "convert_terminal", "read_catio_layout"]
