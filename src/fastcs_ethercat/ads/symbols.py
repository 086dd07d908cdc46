"""Symbol entries (0xF00B upload table, 0xF009 info-by-name answer) and the
upload-info blocks (0xF00C, 0xF00F).

Entry layout (facts file section 4, pyads' SAdsSymbolEntry): entry length,
index group, index offset, size, ADS type id, flags (u32 each); name, type and
comment lengths (u16 each, without NUL) at bytes 24..30; then name, type name
and comment, each NUL-terminated; then optional extras (a 16-byte type GUID
when SymbolFlag.TYPE_GUID is set, attributes, ...) and padding up to the entry
length. Strings are Windows-1252, as TwinCAT writes them.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Final, Self

from fastcs_ethercat.ads.constants import AdsDataType, AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.wire import (
    ByteReader,
    FixedRecord,
    TableEntry,
    encode_text,
    enum_or_int,
    pack,
    read_c_string,
)

SYMBOL_ENTRY_HEADER_SIZE: Final = 30
SYMBOL_ENTRY_ALIGNMENT: Final = 8
"""Entries are padded to a multiple of this. Evidence: pyads' docstring shows a
real TwinCAT 3 entry of 68 bytes + a 16-byte type GUID with entry length 88
(84 rounded up to 8). Readers rely only on the entry length, as pyads does."""
SYMBOL_INFO_SIZE: Final = 1024
"""Read length of one 0xF009 answer (an entry with a long name and comment)."""

_HEADER: Final = struct.Struct("<IIIIIIHHH")


def _padded(length: int, alignment: int) -> int:
    return -(-length // alignment) * alignment if alignment > 1 else length


@dataclass(frozen=True, slots=True)
class AdsSymbolEntry(TableEntry):
    """One symbol: where it lives (group, offset), its size and its type."""

    name: str
    index_group: int
    index_offset: int
    size: int
    data_type: AdsDataType | int
    type_name: str
    comment: str = ""
    flags: int = 0
    extra: bytes = b""
    """Bytes after the comment's NUL up to the entry length (GUID, attributes,
    padding), kept verbatim so re-encoding a decoded entry is byte-exact."""

    def encode(self, alignment: int = SYMBOL_ENTRY_ALIGNMENT) -> bytes:
        """The entry's bytes, padded with zeros to `alignment`."""
        name, type_name, comment = (
            encode_text(self.name),
            encode_text(self.type_name),
            encode_text(self.comment),
        )
        body = name + b"\0" + type_name + b"\0" + comment + b"\0" + bytes(self.extra)
        length = _padded(SYMBOL_ENTRY_HEADER_SIZE + len(body), alignment)
        header = pack(
            _HEADER,
            length,
            self.index_group,
            self.index_offset,
            self.size,
            int(self.data_type),
            self.flags,
            len(name),
            len(type_name),
            len(comment),
            what=f"symbol {self.name!r} field",
        )
        return (header + body).ljust(length, b"\0")

    @classmethod
    def decode_at(
        cls, raw: bytes | bytearray | memoryview, offset: int = 0
    ) -> tuple[Self, int]:
        """Decode the entry starting at `offset`; return it and its length."""
        data = raw if isinstance(raw, bytes) else bytes(raw)
        reader = ByteReader(data, f"symbol entry at offset {offset}", start=offset)
        reader.take(SYMBOL_ENTRY_HEADER_SIZE)  # bounds check before unpacking
        (
            entry_length,
            index_group,
            index_offset,
            size,
            data_type,
            flags,
            name_length,
            type_length,
            comment_length,
        ) = _HEADER.unpack_from(data, offset)
        strings_end = (
            SYMBOL_ENTRY_HEADER_SIZE + name_length + type_length + comment_length + 3
        )
        if entry_length < strings_end:
            raise AdsCodecError(
                f"symbol entry at offset {offset}: entry length {entry_length} is "
                f"shorter than its header and strings ({strings_end})",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        if entry_length > len(data) - offset:
            raise AdsCodecError(
                f"symbol entry at offset {offset}: entry length {entry_length} "
                f"runs past the end of the buffer ({len(data) - offset} bytes left)",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        name = read_c_string(reader, name_length, "name")
        type_name = read_c_string(reader, type_length, "type name")
        comment = read_c_string(reader, comment_length, "comment")
        extra = reader.take(entry_length - strings_end)
        entry = cls(
            name=name,
            index_group=index_group,
            index_offset=index_offset,
            size=size,
            data_type=enum_or_int(AdsDataType, data_type),
            type_name=type_name,
            comment=comment,
            flags=flags,
            extra=extra,
        )
        return entry, entry_length


decode_symbol_table = AdsSymbolEntry.decode_table
"""Every entry of a 0xF00B table (`count` of them, from 0xF00F)."""
encode_symbol_table = AdsSymbolEntry.encode_table
"""Entries back to back, as a 0xF00B read returns them."""


@dataclass(frozen=True, slots=True)
class SymbolUploadInfo(FixedRecord):
    """0xF00C answer: symbol count and symbol table length (8 bytes)."""

    layout = struct.Struct("<II")
    symbol_count: int
    symbol_table_size: int


@dataclass(frozen=True, slots=True)
class SymbolUploadInfo2(FixedRecord):
    """0xF00F answer: six u32 (24 bytes) describing both upload tables."""

    layout = struct.Struct("<6I")
    symbol_count: int
    symbol_table_size: int
    data_type_count: int = 0
    data_type_table_size: int = 0
    max_dynamic_symbols: int = 0
    used_dynamic_symbols: int = 0

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        """Decode 24 bytes; a longer buffer (pyads reads 1024) is accepted."""
        first = ByteReader(raw, cls.__name__).take(cls.layout.size)
        return cls.from_reader(ByteReader(first, cls.__name__))


def encode_symbol_name(name: str) -> bytes:
    """The write data of a by-name request (0xF003, 0xF004, 0xF009): the name
    and a NUL, as pyads sends it."""
    return encode_text(name) + b"\0"
