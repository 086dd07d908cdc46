"""Import catio-terminals' single file (`terminal_types:`) through the ESI.

catio-terminals writes a structure's fields as separate "dotted" symbol nodes
(`AI Standard Channel {channel}.Value` next to `AI Standard Channel
{channel}`, whose own `type_name` is a composite of the status bits), counts
channels instead of listing them, records no PDO indices, CoE addresses or
bit offsets, and keeps only the selected CoE objects. Without offsets such a
file cannot describe a terminal, so it is never loaded as it is: each type
is generated from the ESI description of its own identity (type and
revision), and catio's nodes are matched against it by name to carry over
what catio knows: the `selected` flags, the selected PDO group, the selected
CoE objects and the `fastcs_name`s. Every node or choice that cannot be
placed is reported, one line each.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from fastcs_ethercat.bounded import MAX_CATIO_BYTES, read_text_bounded
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.terminals.files import CATIO_LAYOUT_KEY
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.model import SymbolMember, SymbolNode, TerminalType
from fastcs_ethercat.terminals.names import CHANNEL, expand
from fastcs_ethercat.terminals.selection import (
    SelectionError,
    check_fastcs_name,
    rename_coe,
    rename_symbol,
    select_group,
)
from fastcs_ethercat.terminals.yaml_io import LocatedYaml, parse_yaml, validation_error

COMPOSITE_TYPES_KEY = "composite_types"


class _Catio(BaseModel):
    """catio's own keys only: a typo must not pass as a default."""

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


def read_catio_file(path: Path) -> tuple[LocatedYaml, dict[str, CatioTerminal]]:
    """The validated types of a catio file (unknown keys are errors)."""
    text = read_text_bounded(path, MAX_CATIO_BYTES, what="catio file")
    located = parse_yaml(text, path)
    data = located.data
    if not isinstance(data, dict) or CATIO_LAYOUT_KEY not in data:
        raise UserError(
            f"not a catio-terminals file: no top-level {CATIO_LAYOUT_KEY}: key",
            path=path,
        )
    types = data[CATIO_LAYOUT_KEY]
    if not isinstance(types, dict):
        raise UserError(
            "expected a mapping of terminal types",
            path=path,
            where=located.where((CATIO_LAYOUT_KEY,)),
        )
    result: dict[str, CatioTerminal] = {}
    for name, body in types.items():
        try:
            result[str(name)] = CatioTerminal.model_validate(body)
        except ValidationError as error:
            raise validation_error(located, (CATIO_LAYOUT_KEY, name), error) from None
    return located, result


@dataclass
class ImportResult:
    """One imported type, and every node or choice that could not be placed."""

    type_name: str
    terminal: TerminalType | None
    problems: list[str] = field(default_factory=list)


def import_catio(
    located: LocatedYaml, types: dict[str, CatioTerminal], catalog: EsiCatalog
) -> list[ImportResult]:
    """Each catio type generated from its ESI identity, with catio's choices."""
    results: list[ImportResult] = []
    for name, catio in types.items():
        result = ImportResult(type_name=name, terminal=None)
        results.append(result)
        revision = catio.identity.revision_number
        try:
            device = catalog.load(name, revision)
        except UserError as error:
            result.problems.append(f"no ESI description to import it from: {error}")
            continue
        if device.product_code != catio.identity.product_code:
            result.problems.append(
                f"product code 0x{catio.identity.product_code:08x} is not the ESI's "
                f"0x{device.product_code:08x}"
            )
            continue
        _Importer(located, name, catio, terminal_from_esi(device), result).run()
    return results


class _Importer:
    """catio's choices of one type applied to its ESI-generated terminal."""

    def __init__(
        self,
        located: LocatedYaml,
        name: str,
        catio: CatioTerminal,
        terminal: TerminalType,
        result: ImportResult,
    ) -> None:
        self.located = located
        self.name = name
        self.catio = catio
        self.terminal = terminal
        self.result = result
        self.loc = (CATIO_LAYOUT_KEY, name)

    def problem(self, loc: tuple[Any, ...], message: str) -> None:
        where = self.located.where((*self.loc, *loc))
        self.result.problems.append(f"line {where.split(':')[0]}: {message}")

    def run(self) -> None:
        self._group()
        wanted = self._symbols()
        self._selections(wanted)
        self._coe()
        self.result.terminal = self.terminal

    def _group(self) -> None:
        chosen = self.catio.selected_pdo_group
        if chosen is None or not self.terminal.pdo_groups:
            return
        try:
            self.terminal = select_group(self.terminal, chosen)
        except SelectionError as error:
            self.problem(("selected_pdo_group",), str(error))

    def _symbols(self) -> dict[int, list[bool]]:
        """Node position -> the selected flags of every catio node placed on it."""
        wanted: dict[int, list[bool]] = {}
        placed: dict[tuple[int, str], int] = {}
        for at, symbol in enumerate(self.catio.symbol_nodes):
            loc = ("symbol_nodes", at)
            found = self._place(symbol)
            if found is None:
                self.problem(
                    loc,
                    f"symbol node {symbol.name_template!r} matches no symbol or "
                    f"member of {self.name} revision "
                    f"0x{self.terminal.identity.revision_number:08x}",
                )
                continue
            position, member = found
            key = (position, member.name if member else "")
            if key in placed:
                self.problem(
                    loc,
                    f"symbol node {symbol.name_template!r} repeats symbol_nodes"
                    f"[{placed[key]}]",
                )
                continue
            placed[key] = at
            wanted.setdefault(position, []).append(symbol.selected)
            self._name(loc, symbol, position, member)
        return wanted

    def _place(self, symbol: CatioSymbol) -> tuple[int, SymbolMember | None] | None:
        """(node position, member or None for the node itself)."""
        name = symbol.name_template
        for position, node in enumerate(self.terminal.symbol_nodes):
            if name == node.name_template:
                return position, None
            head = f"{node.name_template}."
            if name.startswith(head):
                member = _member(node, name[len(head) :])
                if member is not None:
                    return position, member
        return None

    def _name(
        self,
        loc: tuple[Any, ...],
        symbol: CatioSymbol,
        position: int,
        member: SymbolMember | None,
    ) -> None:
        wanted = symbol.fastcs_name
        node = self.terminal.symbol_nodes[position]
        if not wanted or wanted == node.fastcs_name:
            return
        if member is None or len(node.members) == 1:
            # a symbol of one member is one attribute: the symbol's name
            try:
                self.terminal = rename_symbol(self.terminal, position, wanted)
            except SelectionError as error:
                self.problem((*loc, "fastcs_name"), f"fastcs_name not kept: {error}")
            return
        prefix = f"{node.fastcs_name}_"
        rest = wanted.removeprefix(prefix)
        try:
            check_fastcs_name(rest, False)
        except SelectionError:
            rest = ""
        taken = {m.fastcs_name for m in node.members if m is not member}
        if not wanted.startswith(prefix) or not rest or rest in taken:
            self.problem(
                (*loc, "fastcs_name"),
                f"fastcs_name {wanted!r} not kept: a member's attribute is "
                f"'{node.fastcs_name}_<member>' here, so it stays "
                f"{prefix}{member.fastcs_name!s}",
            )
            return
        member.fastcs_name = rest

    def _selections(self, wanted: dict[int, list[bool]]) -> None:
        for position, node in enumerate(self.terminal.symbol_nodes):
            flags = wanted.get(position)
            if flags is None:
                continue
            on = any(flags)
            if on and not all(flags):
                self.result.problems.append(
                    f"{node.name_template}: catio selected only some of its "
                    "fields; the whole symbol is selected"
                )
            if on and not self.terminal.selectable(position):
                self.result.problems.append(
                    f"{node.name_template}: selected in catio, but not in the "
                    f"selected PDO group {self.terminal.selected_pdo_group!r}; "
                    "left unselected"
                )
                on = False
            node.selected = on

    def _coe(self) -> None:
        objects = {obj.index: obj for obj in self.terminal.coe_objects}
        for at, catio in enumerate(self.catio.coe_objects):
            loc = ("coe_objects", at)
            obj = objects.get(catio.index)
            if obj is None:
                self.problem(
                    loc,
                    f"CoE object 0x{catio.index:04x} {catio.name!r} is not in the "
                    "ESI dictionary",
                )
                continue
            obj.selected = True
            if catio.fastcs_name and catio.fastcs_name != obj.fastcs_name:
                try:
                    self.terminal = rename_coe(
                        self.terminal, catio.index, catio.fastcs_name
                    )
                    objects = {o.index: o for o in self.terminal.coe_objects}
                except SelectionError as error:
                    self.problem(
                        (*loc, "fastcs_name"), f"fastcs_name not kept: {error}"
                    )


def _member(node: SymbolNode, field_name: str) -> SymbolMember | None:
    """The member catio's dotted field names: `Value`, `Status.Underrange` or
    `Status__Underrange`, with `{channel}` where the node has none."""
    spelled = {field_name, field_name.replace(".", "__")}
    for member in node.members:
        if member.name in spelled:
            return member
    if CHANNEL in field_name and CHANNEL not in node.name_template:
        first = expand(field_name, 1)
        for member in node.members:
            if member.name in (first, first.replace(".", "__")):
                return member
    return None


__all__ = [
    "CatioTerminal",
    "ImportResult",
    "import_catio",
    "read_catio_file",
]
