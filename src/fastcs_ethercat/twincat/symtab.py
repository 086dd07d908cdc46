"""One device's symbol table: the upload bytes, lookup by name, and the
members and array elements below each symbol.

Lookups are case-insensitive, as TwinCAT's symbol services are. A name
reaches a symbol, an alias of a one-entry PDO (`Term 2 (EL1008).Channel
1.Input`, accepted by a real TwinCAT per pyads issue #456 though the upload
lists only `Channel 1`), a member (`...AI Standard Channel 1.Status.Error`)
or an array element (`...Ch1 Sample 0[3]`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Final

from fastcs_ethercat.ads.datatypes import encode_data_type_table
from fastcs_ethercat.ads.symbols import (
    AdsSymbolEntry,
    SymbolUploadInfo,
    SymbolUploadInfo2,
    encode_symbol_table,
)
from fastcs_ethercat.twincat.layout import (
    DeviceLayout,
    ImageArea,
    ImagePlace,
    SymbolDef,
)
from fastcs_ethercat.twincat.tctypes import TcMember, TcType, data_type_entry

_PATH_PART: Final = re.compile(r"\.([^.\[\]]+)|\[\s*(-?\d+)\s*\]")


@dataclass(frozen=True, slots=True)
class Resolved(ImagePlace):
    """Where a name lives: its type and its place in the image."""

    name: str
    type: TcType
    area: ImageArea
    bit_address: int
    symbol: SymbolDef
    """The table entry the name belongs to."""

    def entry(self) -> AdsSymbolEntry:
        """The 0xF009 answer for this name."""
        comment = self.symbol.comment if self.name == self.symbol.name else ""
        return self.symbol_entry(self.name, comment)


class SymbolTable:
    """The symbols of one device port, with their upload bytes precomputed."""

    def __init__(self, layout: DeviceLayout, version: int) -> None:
        self.layout = layout
        self.version = version
        self.symbols = layout.symbols
        self._by_key: dict[str, SymbolDef] = {}
        self._aliases: dict[str, SymbolDef] = {}
        for symbol in self.symbols:
            self._by_key[symbol.name.casefold()] = symbol
            for alias in symbol.aliases:
                self._aliases[alias.casefold()] = symbol
        self._cache: dict[str, Resolved] = {}
        self.upload = encode_symbol_table([symbol.entry() for symbol in self.symbols])
        self.data_types = encode_data_type_table(
            [data_type_entry(kind) for kind in layout.types]
        )
        self.upload_info = SymbolUploadInfo(
            len(self.symbols), len(self.upload)
        ).encode()
        self.upload_info2 = SymbolUploadInfo2(
            symbol_count=len(self.symbols),
            symbol_table_size=len(self.upload),
            data_type_count=len(layout.types),
            data_type_table_size=len(self.data_types),
        ).encode()

    def __len__(self) -> int:
        return len(self.symbols)

    def symbol(self, name: str) -> SymbolDef | None:
        """A table entry by its exact name (case-insensitive)."""
        return self._by_key.get(name.casefold())

    def resolve(self, name: str) -> Resolved | None:
        """Whatever `name` reaches, or None (answered as 0x710)."""
        key = name.strip().casefold()
        found = self._cache.get(key)
        if found is None:
            found = self._resolve(name.strip(), key)
            if found is not None:  # only real names: clients may send anything
                self._cache[key] = found
        return found

    def _resolve(self, name: str, key: str) -> Resolved | None:
        symbol = self._by_key.get(key) or self._aliases.get(key)
        if symbol is not None:
            return Resolved(
                symbol.name if symbol.name.casefold() == key else name,
                symbol.type,
                symbol.area,
                symbol.bit_address,
                symbol,
            )
        for split in _split_points(name):
            symbol = self._by_key.get(key[:split])
            if symbol is not None:
                return _walk(symbol, name[split:])
        return None


def _split_points(name: str) -> list[int]:
    """Positions where a symbol name could end, longest first."""
    points = [i for i, char in enumerate(name) if char in ".["]
    return sorted(points, reverse=True)


def _walk(symbol: SymbolDef, rest: str) -> Resolved | None:
    """Follow `.member` and `[index]` parts below a symbol."""
    kind = symbol.type
    address = symbol.bit_address
    name = symbol.name
    position = 0
    while position < len(rest):
        match = _PATH_PART.match(rest, position)
        if match is None:
            return None
        position = match.end()
        member_name, index = match.group(1), match.group(2)
        if member_name is not None:
            member = _member(kind, member_name.strip())
            if member is None:
                return None
            address += member.bit_offset
            kind = member.type
            name = f"{name}.{member.name}"
        else:
            element = kind.element
            number = int(index)
            offset = number - kind.lower_bound
            if element is None or not 0 <= offset < kind.count:
                return None
            address += offset * element.byte_size * 8
            kind = element
            name = f"{name}[{number}]"
    return Resolved(name, kind, symbol.area, address, symbol)


def _member(kind: TcType, name: str) -> TcMember | None:
    found = kind.member(name)
    if found is not None:
        return found
    folded = name.casefold()
    return next((m for m in kind.members if m.name.casefold() == folded), None)


__all__ = ["Resolved", "SymbolTable"]
