"""Little-endian reading and writing helpers shared by the codec modules.

`ByteReader` walks a buffer with a cursor and raises `AdsCodecError` (never
`struct.error` or `IndexError`) when the buffer is too short, so every decoder
built on it keeps the codec's promise of a single exception type.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator, Sequence
from dataclasses import fields
from enum import IntEnum
from typing import Any, ClassVar, Final, Self, TypeVar, cast

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError

U8: Final = struct.Struct("<B")
U16: Final = struct.Struct("<H")
U32: Final = struct.Struct("<I")
U64: Final = struct.Struct("<Q")

_T = TypeVar("_T")
_E = TypeVar("_E", bound=IntEnum)

STRING_ENCODING: Final = "windows-1252"
"""TwinCAT writes names, type names and comments in the Windows code page."""


def encode_text(text: str) -> bytes:
    """Encode a TwinCAT name or comment; unencodable characters are a codec error."""
    try:
        return text.encode(STRING_ENCODING)
    except UnicodeEncodeError as error:
        raise AdsCodecError(
            f"text {text!r} is not representable in {STRING_ENCODING}",
            AdsReturnCode.DEVICE_INVALID_DATA,
        ) from error


def decode_text(raw: bytes) -> str:
    """Decode a TwinCAT name; bytes undefined in cp1252 map to U+FFFD."""
    return raw.decode(STRING_ENCODING, errors="replace")


def decode_c_string(raw: bytes) -> str:
    """Decode a NUL-padded fixed-size char field up to its first NUL."""
    return decode_text(raw.split(b"\0", 1)[0])


class ByteReader:
    """A cursor over a bytes-like buffer that reads little-endian fields."""

    __slots__ = ("_buffer", "_end", "_position", "what")

    def __init__(
        self,
        buffer: bytes | bytearray | memoryview,
        what: str,
        start: int = 0,
        end: int | None = None,
    ) -> None:
        self._buffer = buffer if isinstance(buffer, bytes) else bytes(buffer)
        self._position = start
        self._end = len(self._buffer) if end is None else min(end, len(self._buffer))
        self.what = what

    @property
    def position(self) -> int:
        return self._position

    @property
    def remaining(self) -> int:
        return self._end - self._position

    def take(self, count: int) -> bytes:
        """Return the next `count` bytes or raise if fewer are left."""
        if count < 0 or count > self.remaining:
            raise AdsCodecError(
                f"{self.what}: need {count} bytes at offset {self._position}, "
                f"only {self.remaining} left",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        start = self._position
        self._position += count
        return self._buffer[start : self._position]

    def u8(self) -> int:
        return U8.unpack(self.take(1))[0]

    def u16(self) -> int:
        return U16.unpack(self.take(2))[0]

    def u32(self) -> int:
        return U32.unpack(self.take(4))[0]

    def u64(self) -> int:
        return U64.unpack(self.take(8))[0]

    def rest(self) -> bytes:
        return self.take(self.remaining)

    def expect_end(self) -> None:
        """Raise if bytes are left over: a payload longer than its layout."""
        if self.remaining:
            raise AdsCodecError(
                f"{self.what}: {self.remaining} unexpected trailing bytes",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )


def pack(layout: str | struct.Struct, *values: object, what: str = "field") -> bytes:
    """`struct.pack` that reports a value out of range as a codec error."""
    try:
        if isinstance(layout, struct.Struct):
            return layout.pack(*values)
        return struct.pack(layout, *values)
    except struct.error as error:
        raise AdsCodecError(
            f"{what} out of range: {error}", AdsReturnCode.DEVICE_INVALID_DATA
        ) from error


def exactly(
    raw: bytes | bytearray | memoryview,
    size: int,
    what: str,
    code: AdsReturnCode = AdsReturnCode.DEVICE_INVALID_SIZE,
) -> ByteReader:
    """A reader over `raw`, which must be `size` bytes long."""
    if len(raw) != size:
        raise AdsCodecError(f"{what} is {size} bytes, got {len(raw)}", code)
    return ByteReader(raw, what)


def read_c_string(reader: ByteReader, length: int, what: str) -> str:
    """A string of known length that must be followed by its NUL."""
    text = reader.take(length)
    if reader.take(1) != b"\0":
        raise AdsCodecError(
            f"{reader.what}: {what} of {length} bytes is not NUL-terminated",
            AdsReturnCode.DEVICE_INVALID_DATA,
        )
    return decode_text(text)


EntryDecoder = Callable[[bytes, int], tuple[_T, int]]
"""decode_at(buffer, offset) -> (entry, its length in bytes)."""


def iter_entries(
    table: bytes | bytearray | memoryview,
    decode_at: EntryDecoder[_T],
    count: int | None = None,
) -> Iterator[_T]:
    """Walk a table of length-prefixed entries (symbols, data types) by each
    entry's own length; stop after `count` if given, else at the end."""
    data = bytes(table)
    position = seen = 0
    while position < len(data) if count is None else seen < count:
        entry, used = decode_at(data, position)
        yield entry
        position += used
        seen += 1


def decode_whole(
    raw: bytes | bytearray | memoryview, decode_at: EntryDecoder[_T]
) -> _T:
    """The one entry that fills `raw` exactly (e.g. a 0xF009 answer)."""
    data = bytes(raw)
    entry, used = decode_at(data, 0)
    if used != len(data):
        raise AdsCodecError(
            f"entry is {used} bytes, buffer has {len(data)}",
            AdsReturnCode.DEVICE_INVALID_SIZE,
        )
    return entry


def enum_or_int(kind: type[_E], value: int) -> _E | int:
    """The member of `kind` for a known value, the bare int for another
    (a peer may send ids this codec does not name)."""
    try:
        return kind(value)
    except ValueError:
        return value


class FixedRecord:
    """Mixin for a dataclass whose fields, in order, are packed as `layout`
    (then `reserved` zero bytes): encode, and decode exactly that many bytes."""

    __slots__ = ()
    layout: ClassVar[struct.Struct]
    reserved: ClassVar[int] = 0

    def encode(self) -> bytes:
        values = [getattr(self, f.name) for f in fields(cast(Any, self))]
        what = f"{type(self).__name__} field"
        return pack(self.layout, *values, what=what) + bytes(self.reserved)

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        reader = exactly(raw, cls.layout.size + cls.reserved, cls.__name__)
        return cls.from_reader(reader)

    @classmethod
    def from_reader(cls, reader: ByteReader) -> Self:
        """The record at the reader's position; the rest must be `reserved`."""
        values = cls.layout.unpack(reader.take(cls.layout.size))
        reader.take(cls.reserved)
        reader.expect_end()
        return cast(Any, cls)(*values)


class TableEntry:
    """Mixin for entries that tables hold back to back, each starting with
    its own length (symbol and data-type entries): whole tables and single
    entries from `decode_at`, tables from `encode`."""

    __slots__ = ()

    @classmethod
    def decode_at(
        cls, raw: bytes | bytearray | memoryview, offset: int = 0
    ) -> tuple[Self, int]:
        """The entry at `offset` and its length."""
        raise NotImplementedError

    def encode(self, alignment: int) -> bytes:
        raise NotImplementedError

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        """The one entry that fills `raw` exactly (e.g. a 0xF009 answer)."""
        return decode_whole(raw, cls.decode_at)

    @classmethod
    def decode_table(
        cls, table: bytes | bytearray | memoryview, count: int | None = None
    ) -> list[Self]:
        """Every entry by its length; with `count` (from 0xF00F) only that
        many, as pyads reads them."""
        return list(iter_entries(table, cls.decode_at, count))

    @staticmethod
    def encode_table(entries: Sequence[TableEntry], alignment: int = 8) -> bytes:
        """Entries back to back, each padded to `alignment`."""
        return b"".join(entry.encode(alignment) for entry in entries)
