"""Data-type entries (0xF00E upload table): recursive, with array dimensions.

Entry layout (facts file section 4): entry length, version, hash, type hash,
size, offset (within a parent), ADS type id, flags (u32 each); name length,
type length, comment length, array dimension count, sub-item count (u16
each); name\\0, type\\0, comment\\0; per dimension (lower bound u32, element
count u32); each sub-item as a full entry (recursive); then optional extras
(type GUID, copy mask, method, attribute and enum infos, per the flags) and
padding to the entry length. The extras are kept verbatim.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final, Self

from fastcs_ethercat.ads.constants import AdsDataType, AdsReturnCode, DataTypeFlag
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.wire import (
    ByteReader,
    TableEntry,
    encode_text,
    enum_or_int,
    pack,
    read_c_string,
)

DATA_TYPE_ENTRY_HEADER_SIZE: Final = 42
DATA_TYPE_ENTRY_ALIGNMENT: Final = 8
"""Padding of each entry, as for symbol entries (unconfirmed for data types;
readers rely only on the entry length)."""
DATA_TYPE_ENTRY_VERSION: Final = 1

_HEADER: Final = struct.Struct("<IIIIIIIIHHHHH")
_DIMENSION: Final = struct.Struct("<iI")


@dataclass(frozen=True, slots=True)
class ArrayDimension:
    """One array dimension: lower bound (signed, e.g. ARRAY [-1..1]) and count."""

    lower_bound: int
    element_count: int


@dataclass(frozen=True, slots=True)
class AdsDataTypeEntry(TableEntry):
    """A data type (top level) or a member of one (sub-item).

    For a top-level entry `name` is the type's name and `type_name` its base
    type (empty for a structure, the element type for an array). For a
    sub-item `name` is the member name, `type_name` its type and `offset` its
    byte offset within the parent.
    """

    name: str
    type_name: str
    size: int
    data_type: AdsDataType | int = AdsDataType.BIGTYPE
    flags: int = DataTypeFlag.DATA_TYPE
    offset: int = 0
    comment: str = ""
    array_dimensions: tuple[ArrayDimension, ...] = ()
    sub_items: tuple[AdsDataTypeEntry, ...] = ()
    version: int = DATA_TYPE_ENTRY_VERSION
    hash_value: int = 0
    type_hash_value: int = 0
    extra: bytes = b""
    """Bytes after the sub-items up to the entry length, verbatim."""

    def encode(self, alignment: int = DATA_TYPE_ENTRY_ALIGNMENT) -> bytes:
        """The entry's bytes (sub-items included), zero-padded to `alignment`."""
        name, type_name, comment = (
            encode_text(self.name),
            encode_text(self.type_name),
            encode_text(self.comment),
        )
        dimensions = b"".join(
            pack(_DIMENSION, d.lower_bound, d.element_count, what="array dimension")
            for d in self.array_dimensions
        )
        body = b"".join(
            (
                name + b"\0",
                type_name + b"\0",
                comment + b"\0",
                dimensions,
                *(item.encode(alignment) for item in self.sub_items),
                bytes(self.extra),
            )
        )
        length = DATA_TYPE_ENTRY_HEADER_SIZE + len(body)
        if alignment > 1:
            length = -(-length // alignment) * alignment
        header = pack(
            _HEADER,
            length,
            self.version,
            self.hash_value,
            self.type_hash_value,
            self.size,
            self.offset,
            int(self.data_type),
            int(self.flags),
            len(name),
            len(type_name),
            len(comment),
            len(self.array_dimensions),
            len(self.sub_items),
            what=f"data type {self.name!r} field",
        )
        return (header + body).ljust(length, b"\0")

    @classmethod
    def decode_at(
        cls,
        raw: bytes | bytearray | memoryview,
        offset: int = 0,
        limit: int | None = None,
        depth: int = 0,
    ) -> tuple[Self, int]:
        """Decode the entry starting at `offset` that must end by `limit`
        (default: the buffer's end); return it and its entry length."""
        data = raw if isinstance(raw, bytes) else bytes(raw)
        limit = len(data) if limit is None else min(limit, len(data))
        if depth > _MAX_DEPTH:
            raise AdsCodecError(
                f"data type entry at offset {offset}: sub-items nested deeper "
                f"than {_MAX_DEPTH}",
                AdsReturnCode.DEVICE_INVALID_DATA,
            )
        what = f"data type entry at offset {offset}"
        reader = ByteReader(data, what, start=offset, end=limit)
        reader.take(DATA_TYPE_ENTRY_HEADER_SIZE)
        (
            entry_length,
            version,
            hash_value,
            type_hash_value,
            size,
            member_offset,
            data_type,
            flags,
            name_length,
            type_length,
            comment_length,
            dimension_count,
            sub_item_count,
        ) = _HEADER.unpack_from(data, offset)
        end = offset + entry_length
        if entry_length < DATA_TYPE_ENTRY_HEADER_SIZE or end > limit:
            raise AdsCodecError(
                f"{what}: entry length {entry_length} does not fit the buffer "
                f"({limit - offset} bytes left)",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        # Bound the reader to this entry so nothing spills into the next one.
        reader = ByteReader(data, what, start=reader.position, end=end)
        name = read_c_string(reader, name_length, "name")
        type_name = read_c_string(reader, type_length, "type name")
        comment = read_c_string(reader, comment_length, "comment")
        dimensions = tuple(
            ArrayDimension(*_DIMENSION.unpack(reader.take(_DIMENSION.size)))
            for _ in range(dimension_count)
        )
        sub_items: list[AdsDataTypeEntry] = []
        position = reader.position
        for _ in range(sub_item_count):
            item, used = AdsDataTypeEntry.decode_at(data, position, end, depth + 1)
            sub_items.append(item)
            position += used
        extra = data[position:end]
        entry = cls(
            name=name,
            type_name=type_name,
            size=size,
            data_type=enum_or_int(AdsDataType, data_type),
            flags=flags,
            offset=member_offset,
            comment=comment,
            array_dimensions=dimensions,
            sub_items=tuple(sub_items),
            version=version,
            hash_value=hash_value,
            type_hash_value=type_hash_value,
            extra=extra,
        )
        return entry, entry_length


_MAX_DEPTH: Final = 32


decode_data_type_table = AdsDataTypeEntry.decode_table
"""Every entry of a 0xF00E table (`count` of them, from 0xF00F)."""
encode_data_type_table = AdsDataTypeEntry.encode_table
"""Entries back to back, as a 0xF00E read returns them."""


# -- layouts ----------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class MemberLayout:
    """A leaf of a (nested) type: where its bytes are from the type's start.

    `path` is dotted from the top type ("Status.Underrange"; "" for a type
    without members); TwinCAT reaches it as `<symbol>.<path>`. A byte leaf
    has `offset` and `size` in bytes. A bit field (flag BIT_VALUES) sits in
    the structure that holds it: `offset` and `size` are that structure's
    bytes, `bit_offset` and `bit_size` its bits from there. A leaf with
    `dimensions` is an array of `type_name` elements (a named array type such
    as `Ch1 Sample 0_TYPE_ARR`); an array member carries its own
    `ARRAY [a..b] OF T` type name instead.
    """

    path: str
    type_name: str
    data_type: AdsDataType | int
    offset: int
    size: int
    bit_offset: int = 0
    bit_size: int = 0
    dimensions: tuple[ArrayDimension, ...] = ()


MAX_MEMBER_DEPTH: Final = 8
"""I/O types nest two or three deep; a type table that nests deeper (or
refers to itself) is cut there instead of being followed forever."""


def walk_members(
    entry: AdsDataTypeEntry,
    types: Mapping[str, AdsDataTypeEntry] | None = None,
) -> list[MemberLayout]:
    """Every leaf of `entry`, offsets from its start, in member order.

    A member whose own sub-items are not inlined is followed through `types`
    (the data-type table by name), as TwinCAT lists each type once.
    """
    found: list[MemberLayout] = []
    _walk(entry, types or {}, "", 0, found, 0)
    return found


def _walk(
    entry: AdsDataTypeEntry,
    types: Mapping[str, AdsDataTypeEntry],
    prefix: str,
    base: int,
    found: list[MemberLayout],
    depth: int,
) -> None:
    if depth > MAX_MEMBER_DEPTH:
        return
    if not entry.sub_items:
        found.append(
            MemberLayout(
                prefix.rstrip("."),
                entry.type_name,
                entry.data_type,
                base,
                entry.size,
                dimensions=entry.array_dimensions,
            )
        )
        return
    for item in entry.sub_items:
        path = f"{prefix}{item.name}"
        if item.flags & DataTypeFlag.BIT_VALUES:
            found.append(
                MemberLayout(
                    path,
                    item.type_name,
                    item.data_type,
                    base,
                    max(entry.size, 1),
                    bit_offset=item.offset,
                    bit_size=item.size,
                )
            )
            continue
        nested = item if item.sub_items else types.get(item.type_name)
        if nested is not None and (nested.sub_items or nested.array_dimensions):
            _walk(nested, types, f"{path}.", base + item.offset, found, depth + 1)
            continue
        found.append(
            MemberLayout(
                path, item.type_name, item.data_type, base + item.offset, item.size
            )
        )
