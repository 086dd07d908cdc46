"""TwinCAT data types of the I/O image, built from PDO entries the way
TwinCAT builds them, and named the way TwinCAT names them.

Rules (facts file sections 4 and 7, plus real symbol dumps; see
`sim/__init__.py` for the evidence):

- A PDO with one entry is a plain variable of the entry's type; a 1-bit
  entry is a `BIT` in the bit image.
- A PDO with several entries is a structure `<PDO name>_TYPE` (BIGTYPE).
  Entries named `Group__Item` become members of a nested structure `Group`
  (`Status__Underrange` -> `Status.Underrange`); `Group__ARRAY [i]` becomes
  an array member `Group`.
- Structures are packed: every member sits at the bit offset the PDO gives
  it. Bit-sized members count offset and size in bits.
- One type per PDO family and layout: the channels of one PDO template share
  the first channel's type (all four EL3104 channels have `AI Standard
  Channel 1_TYPE`, as catio's lookups of real racks expect), and so do other
  terminals with the same PDO name and layout; a different layout under a
  name already taken is numbered (`CNT Inputs_2_TYPE`, facts section 7).
- An oversampled PDO (`Ch1 Sample 0`) is an array `<name>_TYPE_ARR` of its
  samples (facts section 7, EL3702).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Final

from fastcs_ethercat.ads.constants import AdsDataType, DataTypeFlag
from fastcs_ethercat.ads.datatypes import AdsDataTypeEntry, ArrayDimension
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.values import TwinCatType, array_type_name, parse_type

NESTING_SEPARATOR: Final = "__"
_ARRAY_ITEM = re.compile(r"^ARRAY\s*\[(-?\d+)\]$")
_FALLBACK_BY_BITS: Final = {8: "USINT", 16: "UINT", 32: "UDINT", 64: "ULINT"}


@dataclass(frozen=True, slots=True, eq=False)
class TcMember:
    """A member of a structure at a bit offset from the structure's start."""

    name: str
    type: TcType
    bit_offset: int

    @property
    def in_bits(self) -> bool:
        """Whether offset and size must be counted in bits (a bit field)."""
        return (
            self.type.is_bit or self.bit_offset % 8 != 0 or self.type.bit_size % 8 != 0
        )


@dataclass(frozen=True, slots=True, eq=False)
class TcType:
    """A TwinCAT type: a scalar, a structure or an array."""

    name: str
    ads_type: int
    bit_size: int
    members: tuple[TcMember, ...] = ()
    element: TcType | None = None
    lower_bound: int = 0
    count: int = 0
    scalar: TwinCatType | None = None
    named: bool = False
    """Listed in the data-type table (structures and named arrays)."""
    _members_by_name: dict[str, TcMember] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        self._members_by_name.update({member.name: member for member in self.members})

    @property
    def is_bit(self) -> bool:
        """A bit-image scalar (BIT, BIT2..BIT8, a 1-bit BOOL)."""
        return self.scalar is not None and self.bit_size < 8

    @property
    def byte_size(self) -> int:
        return (self.bit_size + 7) // 8

    @property
    def symbol_size(self) -> int:
        """Size a symbol entry reports: bit fields read as one byte each."""
        return 1 if self.is_bit else self.byte_size

    def member(self, name: str) -> TcMember | None:
        return self._members_by_name.get(name)

    def signature(self) -> tuple[Any, ...]:
        """What makes two types the same layout (names do not count)."""
        if self.scalar is not None:
            return ("scalar", self.scalar.name, self.bit_size)
        if self.element is not None:
            return (
                "array",
                self.element.signature(),
                self.lower_bound,
                self.count,
            )
        return (
            "struct",
            self.bit_size,
            tuple((m.name, m.bit_offset, m.type.signature()) for m in self.members),
        )


def scalar_type(type_name: str, bit_size: int) -> TcType:
    """The TwinCAT scalar for an entry's data type and bit length.

    A 1-bit BOOL is a BIT (TwinCAT's I/O tree shows entries that way);
    unknown ESI types (enums such as DT0800EN03) fall back by size.
    """
    name = type_name.strip().upper()
    if bit_size < 8:
        name = "BIT" if bit_size == 1 else f"BIT{bit_size}"
    try:
        parsed = parse_type(name)
    except AdsCodecError:
        fallback = _FALLBACK_BY_BITS.get(bit_size)
        if fallback is None:
            raise AdsCodecError(
                f"no TwinCAT type for {type_name!r} of {bit_size} bits"
            ) from None
        parsed = parse_type(fallback)
    if bit_size >= 8 and parsed.size * 8 != bit_size:
        fallback = _FALLBACK_BY_BITS.get(bit_size)
        if fallback is None:
            raise AdsCodecError(
                f"type {type_name!r} is {parsed.size * 8} bits, the entry {bit_size}"
            )
        parsed = parse_type(fallback)
    return TcType(
        name=parsed.name,
        ads_type=int(parsed.ads_type),
        bit_size=bit_size,
        scalar=parsed,
    )


def array_of(element: TcType, count: int, lower_bound: int = 0) -> TcType:
    """An unnamed array (`ARRAY [a..b] OF T`) as a structure member."""
    return TcType(
        name=array_type_name(lower_bound, lower_bound + count - 1, element.name),
        ads_type=element.ads_type
        if element.scalar is not None
        else AdsDataType.BIGTYPE,
        bit_size=element.byte_size * 8 * count,
        element=element,
        lower_bound=lower_bound,
        count=count,
    )


@dataclass(frozen=True, slots=True)
class EntrySpec:
    """One PDO entry (gaps left out) with its bit offset in the PDO."""

    name: str
    type_name: str
    bit_offset: int
    bit_size: int


class TypeNamer:
    """The data-type table of one device: one type per layout, unique names."""

    def __init__(self) -> None:
        self._by_layout: dict[tuple[str, tuple[Any, ...]], TcType] = {}
        self._names: set[str] = set()
        self.types: list[TcType] = []
        """Named types in the order they were first needed."""

    def register(
        self,
        base: str,
        build: TcType,
        suffix: str = "_TYPE",
        family: str | None = None,
    ) -> TcType:
        """The type for `build`'s layout: the one already made for the same
        family (PDO template, default `base`) and layout, or `build` renamed
        `<base><suffix>` (numbered if the name is taken)."""
        key = (family or base, build.signature())
        existing = self._by_layout.get(key)
        if existing is not None:
            return existing
        name = f"{base}{suffix}"
        number = 2
        while name in self._names:
            name = f"{base}_{number}{suffix}"
            number += 1
        named = replace(build, name=name, ads_type=AdsDataType.BIGTYPE, named=True)
        self._by_layout[key] = named
        self._names.add(name)
        self.types.append(named)
        return named


def pdo_type(
    pdo_name: str,
    entries: Sequence[EntrySpec],
    bit_size: int,
    namer: TypeNamer,
    family: str | None = None,
) -> TcType:
    """The type of one PDO instance (one sample of an oversampled PDO);
    `family` (the PDO's name template) decides which PDOs share a type."""
    if len(entries) == 1 and NESTING_SEPARATOR not in entries[0].name:
        entry = entries[0]
        return scalar_type(entry.type_name, entry.bit_size)
    family = family or pdo_name
    members = _members(pdo_name, family, entries, bit_size, namer)
    build = TcType(
        name="",
        ads_type=AdsDataType.BIGTYPE,
        bit_size=_bytes(bit_size),
        members=members,
    )
    return namer.register(pdo_name, build, family=family)


def _bytes(bit_size: int) -> int:
    """Whole bytes, in bits (PDOs and structures end on a byte)."""
    return -(-bit_size // 8) * 8


def _members(
    pdo_name: str,
    family: str,
    entries: Sequence[EntrySpec],
    bit_size: int,
    namer: TypeNamer,
) -> tuple[TcMember, ...]:
    """Top-level members, grouping `Group__Item` entries into one member."""
    ordered = sorted(entries, key=lambda e: e.bit_offset)
    groups: list[tuple[str, bool, list[EntrySpec]]] = []
    for entry in ordered:
        head, separator, _ = entry.name.partition(NESTING_SEPARATOR)
        nested = bool(separator)
        if nested and groups and groups[-1][1] and groups[-1][0] == head:
            groups[-1][2].append(entry)
        else:
            groups.append((head if nested else entry.name, nested, [entry]))
    members: list[TcMember] = []
    for position, (key, nested, group) in enumerate(groups):
        start = group[0].bit_offset
        following = (
            groups[position + 1][2][0].bit_offset
            if position + 1 < len(groups)
            else None
        )
        end = bit_size if following is None else following
        if not nested:
            entry = group[0]
            kind = scalar_type(entry.type_name, entry.bit_size)
        else:
            kind = _group_type(pdo_name, family, key, group, end - start, namer)
        members.append(TcMember(key, kind, start))
    return tuple(members)


def _group_type(
    pdo_name: str,
    family: str,
    key: str,
    group: list[EntrySpec],
    span: int,
    namer: TypeNamer,
) -> TcType:
    """The type of a `Group__...` member: an array or a nested structure."""
    start = group[0].bit_offset
    items = [(entry.name.split(NESTING_SEPARATOR, 1)[1], entry) for entry in group]
    indices = [_ARRAY_ITEM.match(item) for item, _ in items]
    if all(indices):
        first = group[0]
        element = scalar_type(first.type_name, first.bit_size)
        lows = [int(match.group(1)) for match in indices if match is not None]
        return array_of(element, len(group), min(lows))
    inner = [
        EntrySpec(item, entry.type_name, entry.bit_offset - start, entry.bit_size)
        for item, entry in items
    ]
    span = max(span, max(e.bit_offset + e.bit_size for e in inner))
    nested = f"{family}.{key}"
    members = _members(f"{pdo_name}_{key}", nested, inner, span, namer)
    build = TcType(
        name="", ads_type=AdsDataType.BIGTYPE, bit_size=span, members=members
    )
    return namer.register(f"{pdo_name}_{key}", build, family=nested)


def structure(
    name: str, fields: Sequence[tuple[str, str, int]], byte_size: int
) -> TcType:
    """A fixed structure from (member, scalar type, byte offset) triples, for
    the runtime types TwinCAT adds (the master's Inputs / Outputs)."""
    members = tuple(
        TcMember(
            member, scalar_type(type_name, parse_type(type_name).size * 8), 8 * offset
        )
        for member, type_name, offset in fields
    )
    return TcType(
        name=name,
        ads_type=AdsDataType.BIGTYPE,
        bit_size=8 * byte_size,
        members=members,
        named=True,
    )


def data_type_entry(tc_type: TcType) -> AdsDataTypeEntry:
    """The 0xF00E entry of a named type; members refer to types by name."""
    if tc_type.element is not None:
        element = tc_type.element
        return AdsDataTypeEntry(
            name=tc_type.name,
            type_name=element.name,
            size=tc_type.byte_size,
            data_type=AdsDataType.BIGTYPE,
            flags=DataTypeFlag.DATA_TYPE,
            array_dimensions=(ArrayDimension(tc_type.lower_bound, tc_type.count),),
        )
    return AdsDataTypeEntry(
        name=tc_type.name,
        type_name="",
        size=tc_type.byte_size,
        data_type=AdsDataType.BIGTYPE,
        flags=DataTypeFlag.DATA_TYPE,
        sub_items=tuple(_member_entry(member) for member in tc_type.members),
    )


def _member_entry(member: TcMember) -> AdsDataTypeEntry:
    kind = member.type
    flags = DataTypeFlag.DATA_ITEM
    if member.in_bits:
        flags |= DataTypeFlag.BIT_VALUES
        offset, size = member.bit_offset, kind.bit_size
    else:
        offset, size = member.bit_offset // 8, kind.byte_size
    dimensions: tuple[ArrayDimension, ...] = ()
    if kind.element is not None and not kind.named:
        dimensions = (ArrayDimension(kind.lower_bound, kind.count),)
    return AdsDataTypeEntry(
        name=member.name,
        type_name=kind.name,
        size=size,
        data_type=kind.ads_type,
        flags=flags,
        offset=offset,
        array_dimensions=dimensions,
    )


__all__ = [
    "EntrySpec",
    "TcMember",
    "TcType",
    "TypeNamer",
    "array_of",
    "data_type_entry",
    "pdo_type",
    "scalar_type",
    "structure",
]
