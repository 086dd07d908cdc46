"""ADS sum commands: many sub-requests in one ReadWrite (facts section 3).

All travel as a ReadWrite whose index offset is the item count n:

- 0xF080 sum read: write n x (group, offset, length); read n x result u32,
  then every item's data at its requested length (zero-filled for an item that
  failed, which is what pyads' `adsSumRead` walks over).
- 0xF081 sum write: write n x (group, offset, length) then all data; read
  n x result u32.
- 0xF082 sum read-write: write n x (group, offset, read length, write length)
  then all write data; read n x (result u32, returned length u32), then the
  returned data back to back.
- 0xF085 / 0xF086 bulk add / delete notifications: write n x the
  AddDeviceNotification payload / n x handle u32; read n x (result, handle) /
  n x result.

Every sub-item carries its own result; one failing does not fail the others.
Beckhoff recommends at most MAX_SUM_SUB_COMMANDS (500) items per request.
"""

from __future__ import annotations

import itertools
import operator
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Final, Self, TypeVar

import numpy as np
import numpy.typing as npt

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    ReadRequest,
    ReadWriteRequest,
    WriteRequest,
)
from fastcs_ethercat.ads.constants import (
    MAX_SUM_SUB_COMMANDS,
    AdsReturnCode,
    IndexGroup,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.values import structured_dtype
from fastcs_ethercat.ads.wire import ByteReader, pack

_ADD_NOTIFICATION_SIZE: Final = 40
_ITEM_FIELDS: Final = operator.attrgetter("index_group", "index_offset", "length")
_T = TypeVar("_T")

__all__ = [
    "MAX_SUM_SUB_COMMANDS",
    "SumAddNotificationsRequest",
    "SumAddNotificationsResponse",
    "SumDeleteNotificationsRequest",
    "SumDeleteNotificationsResponse",
    "SumReadItem",
    "SumReadLayout",
    "SumReadRequest",
    "SumReadResponse",
    "SumReadWriteItem",
    "SumReadWriteRequest",
    "SumReadWriteResponse",
    "SumWriteItem",
    "SumWriteRequest",
    "SumWriteResponse",
    "chunked",
]


def chunked(
    items: Sequence[_T], size: int = MAX_SUM_SUB_COMMANDS
) -> Iterator[Sequence[_T]]:
    """Split a list of sub-requests into sum requests of at most `size`."""
    for start in range(0, len(items), size):
        yield items[start : start + size]


def _need(raw_length: int, needed: int, what: str) -> None:
    if raw_length < needed:
        raise AdsCodecError(
            f"{what}: needs at least {needed} bytes, got {raw_length}",
            AdsReturnCode.DEVICE_INVALID_SIZE,
        )


def _results(reader: ByteReader, count: int) -> tuple[int, ...]:
    _need(reader.remaining, 4 * count, reader.what)
    return tuple(reader.u32() for _ in range(count))


# -- 0xF080 sum read --------------------------------------------------------


SumReadItem = ReadRequest
"""A sum read's sub-request is a Read's: group, offset, length."""


class SumReadLayout:
    """Where everything sits in a 0xF080 answer: n results (u32) first, then
    every item's data at its requested length, back to back (zeros for an
    item that failed). The one description of it, for the client that views
    answers with numpy and the simulator that builds them."""

    __slots__ = ("data_offsets", "lengths", "size")

    def __init__(self, lengths: Sequence[int]) -> None:
        self.lengths = tuple(lengths)
        count = len(self.lengths)
        offsets = np.empty(count, dtype=np.intp)
        if count:
            offsets[0] = 4 * count
            np.cumsum(np.asarray(self.lengths[:-1], dtype=np.intp), out=offsets[1:])
            offsets[1:] += offsets[0]
        self.data_offsets: npt.NDArray[np.intp] = offsets
        """Byte offset of each item's data within the answer."""
        self.size = 4 * count + sum(self.lengths)
        """Bytes of the whole answer."""

    @classmethod
    def of(cls, items: Sequence[SumReadItem]) -> SumReadLayout:
        return cls([item.length for item in items])

    @property
    def count(self) -> int:
        return len(self.lengths)

    def dtype(self, fields: Sequence[tuple[str, Any, int]]) -> np.dtype[Any]:
        """A structured dtype of the whole answer: field `results` (the n
        results) plus (name, dtype, byte offset in the answer) fields, so one
        `np.frombuffer` views a whole answer."""
        results = ("results", np.dtype(("<u4", (self.count,))), 0)
        return structured_dtype([results, *fields], self.size)

    def split(
        self, answer: bytes | bytearray | memoryview
    ) -> tuple[tuple[int, ...], tuple[bytes, ...]]:
        """(results, data per item) of an answer of exactly `size` bytes."""
        if len(answer) != self.size:
            raise AdsCodecError(
                f"sum read answer of {self.count} items is {len(answer)} bytes, "
                f"expected {self.size}",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        data = bytes(answer)
        results = struct.unpack_from(f"<{self.count}I", data)
        return results, tuple(
            data[start : start + length]
            for start, length in zip(
                self.data_offsets.tolist(), self.lengths, strict=True
            )
        )

    def encode(self, results: Sequence[int], data: Sequence[bytes]) -> bytes:
        """The answer: results, then each item's data zero-padded to its
        length (a failed item's data is not sent); longer data is an error."""
        if len(results) != self.count or len(data) != self.count:
            raise AdsCodecError(
                f"{self.count} sum read items, {len(results)} results and "
                f"{len(data)} data blocks",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        blocks: list[bytes] = []
        for result, value, length in zip(results, data, self.lengths, strict=True):
            if result != AdsReturnCode.NO_ERROR:
                value = b""
            if len(value) > length:
                raise AdsCodecError(
                    f"sum read item wants {length} bytes, got {len(value)}",
                    AdsReturnCode.DEVICE_INVALID_SIZE,
                )
            blocks.append(bytes(value).ljust(length, b"\0"))
        return pack(f"<{self.count}I", *results) + b"".join(blocks)


@dataclass(frozen=True, slots=True)
class SumReadRequest:
    """The write data of a 0xF080 ReadWrite (n x 12 bytes)."""

    items: tuple[SumReadItem, ...]

    @property
    def read_length(self) -> int:
        """Bytes the answer holds: n results plus every item's data."""
        return 4 * len(self.items) + sum(item.length for item in self.items)

    def encode(self) -> bytes:
        # One C-level pack: this runs for every request of every poll cycle.
        values = itertools.chain.from_iterable(map(_ITEM_FIELDS, self.items))
        return pack(f"<{3 * len(self.items)}I", *values, what="sum read item")

    def to_read_write(self) -> ReadWriteRequest:
        return ReadWriteRequest(
            IndexGroup.SUMUP_READ, len(self.items), self.read_length, self.encode()
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        """Decode the write data; `count` is the ReadWrite's index offset."""
        reader = ByteReader(raw, "sum read request")
        _need(reader.remaining, 12 * count, reader.what)
        reader.take(12 * count)
        reader.expect_end()
        # One C-level pass over the items: this decode runs on every poll cycle.
        fields = struct.iter_unpack("<III", bytes(raw))
        return cls(tuple(SumReadItem(*item) for item in fields))


@dataclass(frozen=True, slots=True)
class SumReadResponse:
    """Per-item results and data (each at its requested length)."""

    results: tuple[int, ...]
    data: tuple[bytes, ...]

    @classmethod
    def for_items(
        cls, items: Sequence[SumReadItem], outcomes: Sequence[tuple[int, bytes]]
    ) -> Self:
        """Build the answer from (result, data) per item: failed items get
        zeros, short data is zero-padded, long data is an error."""
        layout = SumReadLayout.of(items)
        answer = layout.encode(
            [result for result, _ in outcomes], [value for _, value in outcomes]
        )
        return cls(*layout.split(answer))

    def encode(self) -> bytes:
        return SumReadLayout([len(d) for d in self.data]).encode(
            self.results, self.data
        )

    @classmethod
    def decode(
        cls, raw: bytes | bytearray | memoryview, lengths: Sequence[int]
    ) -> Self:
        """Decode with the requested lengths (the client knows them)."""
        return cls(*SumReadLayout(lengths).split(raw))


# -- 0xF081 sum write -------------------------------------------------------


SumWriteItem = WriteRequest
"""A sum write's sub-request is a Write's: group, offset, data."""


@dataclass(frozen=True, slots=True)
class SumWriteRequest:
    """The write data of a 0xF081 ReadWrite: n headers then all data."""

    items: tuple[SumWriteItem, ...]

    @property
    def read_length(self) -> int:
        return 4 * len(self.items)

    def encode(self) -> bytes:
        headers = b"".join(
            pack("<III", i.index_group, i.index_offset, len(i.data)) for i in self.items
        )
        return headers + b"".join(bytes(i.data) for i in self.items)

    def to_read_write(self) -> ReadWriteRequest:
        return ReadWriteRequest(
            IndexGroup.SUMUP_WRITE, len(self.items), self.read_length, self.encode()
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum write request")
        _need(reader.remaining, 12 * count, reader.what)
        headers = [(reader.u32(), reader.u32(), reader.u32()) for _ in range(count)]
        _need(reader.remaining, sum(length for _, _, length in headers), reader.what)
        items = tuple(
            SumWriteItem(group, offset, reader.take(length))
            for group, offset, length in headers
        )
        reader.expect_end()
        return cls(items)


@dataclass(frozen=True, slots=True)
class SumWriteResponse:
    results: tuple[int, ...]

    def encode(self) -> bytes:
        return pack(f"<{len(self.results)}I", *self.results)

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum write response")
        results = _results(reader, count)
        reader.expect_end()
        return cls(results)


# -- 0xF082 sum read-write --------------------------------------------------


SumReadWriteItem = ReadWriteRequest
"""A sum read-write's sub-request is a ReadWrite's: group, offset, read
length, data."""


@dataclass(frozen=True, slots=True)
class SumReadWriteRequest:
    """The write data of a 0xF082 ReadWrite: n headers then all write data."""

    items: tuple[SumReadWriteItem, ...]

    @property
    def read_length(self) -> int:
        """Largest answer: n x (result, length) plus every read length."""
        return 8 * len(self.items) + sum(i.read_length for i in self.items)

    def encode(self) -> bytes:
        headers = b"".join(
            pack("<IIII", i.index_group, i.index_offset, i.read_length, len(i.data))
            for i in self.items
        )
        return headers + b"".join(bytes(i.data) for i in self.items)

    def to_read_write(self) -> ReadWriteRequest:
        return ReadWriteRequest(
            IndexGroup.SUMUP_READ_WRITE,
            len(self.items),
            self.read_length,
            self.encode(),
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum read-write request")
        _need(reader.remaining, 16 * count, reader.what)
        headers = [
            (reader.u32(), reader.u32(), reader.u32(), reader.u32())
            for _ in range(count)
        ]
        _need(reader.remaining, sum(h[3] for h in headers), reader.what)
        items = tuple(
            SumReadWriteItem(group, offset, read_length, reader.take(write_length))
            for group, offset, read_length, write_length in headers
        )
        reader.expect_end()
        return cls(items)


@dataclass(frozen=True, slots=True)
class SumReadWriteResponse:
    """Per item: result and the data actually returned (its own length)."""

    results: tuple[int, ...]
    data: tuple[bytes, ...]

    def encode(self) -> bytes:
        if len(self.results) != len(self.data):
            raise AdsCodecError(
                "sum read-write response needs one data block per result",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        headers = b"".join(
            pack("<II", result, len(data))
            for result, data in zip(self.results, self.data, strict=True)
        )
        return headers + b"".join(bytes(d) for d in self.data)

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum read-write response")
        _need(reader.remaining, 8 * count, reader.what)
        pairs = [(reader.u32(), reader.u32()) for _ in range(count)]
        _need(reader.remaining, sum(length for _, length in pairs), reader.what)
        data = tuple(reader.take(length) for _, length in pairs)
        reader.expect_end()
        return cls(tuple(result for result, _ in pairs), data)


# -- 0xF085 / 0xF086 bulk notifications --------------------------------------


@dataclass(frozen=True, slots=True)
class SumAddNotificationsRequest:
    items: tuple[AddDeviceNotificationRequest, ...]

    @property
    def read_length(self) -> int:
        return 8 * len(self.items)

    def encode(self) -> bytes:
        return b"".join(item.encode() for item in self.items)

    def to_read_write(self) -> ReadWriteRequest:
        return ReadWriteRequest(
            IndexGroup.SUMUP_ADD_DEVICE_NOTIFICATION,
            len(self.items),
            self.read_length,
            self.encode(),
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        data = bytes(raw)
        if len(data) != _ADD_NOTIFICATION_SIZE * count:
            raise AdsCodecError(
                f"sum add-notification request: {count} items need "
                f"{_ADD_NOTIFICATION_SIZE * count} bytes, got {len(data)}",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        return cls(
            tuple(
                AddDeviceNotificationRequest.decode(
                    data[i : i + _ADD_NOTIFICATION_SIZE]
                )
                for i in range(0, len(data), _ADD_NOTIFICATION_SIZE)
            )
        )


@dataclass(frozen=True, slots=True)
class SumAddNotificationsResponse:
    results: tuple[int, ...]
    handles: tuple[int, ...]

    def encode(self) -> bytes:
        if len(self.results) != len(self.handles):
            raise AdsCodecError(
                "one handle per result", AdsReturnCode.DEVICE_INVALID_SIZE
            )
        return b"".join(
            pack("<II", r, h) for r, h in zip(self.results, self.handles, strict=True)
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum add-notification response")
        _need(reader.remaining, 8 * count, reader.what)
        pairs = [(reader.u32(), reader.u32()) for _ in range(count)]
        reader.expect_end()
        return cls(tuple(r for r, _ in pairs), tuple(h for _, h in pairs))


@dataclass(frozen=True, slots=True)
class SumDeleteNotificationsRequest:
    handles: tuple[int, ...]

    @property
    def read_length(self) -> int:
        return 4 * len(self.handles)

    def encode(self) -> bytes:
        return pack(f"<{len(self.handles)}I", *self.handles)

    def to_read_write(self) -> ReadWriteRequest:
        return ReadWriteRequest(
            IndexGroup.SUMUP_DELETE_DEVICE_NOTIFICATION,
            len(self.handles),
            self.read_length,
            self.encode(),
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum delete-notification request")
        handles = _results(reader, count)
        reader.expect_end()
        return cls(handles)


@dataclass(frozen=True, slots=True)
class SumDeleteNotificationsResponse:
    results: tuple[int, ...]

    def encode(self) -> bytes:
        return pack(f"<{len(self.results)}I", *self.results)

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview, count: int) -> Self:
        reader = ByteReader(raw, "sum delete-notification response")
        results = _results(reader, count)
        reader.expect_end()
        return cls(results)
