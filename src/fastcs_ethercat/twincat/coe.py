"""A slave's CoE object dictionary, filled with the ESI defaults, served as
SDO reads and writes (group 0xF302, offset = index << 16 | subindex, bit 8 =
complete access; facts sections 3 and 6).

Each object is a little bit image laid out by the ESI bit offsets of its
sub-indices, so a single sub-index and a complete access read the same bytes.
Answers for what the dictionary refuses (unconfirmed against a real
TwinCAT, which turns SDO abort codes into ADS errors):

- unknown object or sub-index (SDO abort 0x06020000 / 0x06090011): 0x703
  (invalid index offset, the offset names the object)
- write to a read-only / read of a write-only entry (0x06010002 / 0x06010001):
  0x704 (reading/writing not permitted)
- wrong length (0x06070010): 0x705
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import astuple, dataclass
from typing import Final

from fastcs_ethercat.ads.constants import COE_COMPLETE_ACCESS_FLAG, AdsReturnCode
from fastcs_ethercat.ads.ethercat import SlaveIdentity
from fastcs_ethercat.terminals.model import CoeObject
from fastcs_ethercat.twincat.answers import fit
from fastcs_ethercat.twincat.image import get_bits, raw_bytes, set_bits

IDENTITY_INDEX: Final = 0x1018


@dataclass(slots=True)
class CoeEntry:
    """One sub-index: where its bits are in the object and who may touch it."""

    subindex: int
    bit_offset: int
    bit_size: int
    readable: bool
    writable: bool
    is_string: bool = False


@dataclass(slots=True)
class CoeObjectStore:
    """One object's bytes and entries."""

    index: int
    data: bytearray
    entries: dict[int, CoeEntry]

    def read(self, subindex: int, complete: bool) -> tuple[int, bytes]:
        if complete:
            entry = self.entries.get(subindex)
            if entry is None:
                return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
            return AdsReturnCode.NO_ERROR, bytes(self.data[entry.bit_offset // 8 :])
        entry = self.entries.get(subindex)
        if entry is None:
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        if not entry.readable:
            return AdsReturnCode.DEVICE_INVALID_ACCESS, b""
        value = raw_bytes(self.data, entry.bit_offset, entry.bit_size)
        if entry.is_string:
            value = value.split(b"\0", 1)[0]
        return AdsReturnCode.NO_ERROR, value

    def write(self, subindex: int, data: bytes, complete: bool) -> int:
        entry = self.entries.get(subindex)
        if entry is None:
            return AdsReturnCode.DEVICE_INVALID_OFFSET
        if complete:
            start = entry.bit_offset // 8
            if start + len(data) > len(self.data):
                return AdsReturnCode.DEVICE_INVALID_SIZE
            targets = [
                e for e in self.entries.values() if e.bit_offset >= entry.bit_offset
            ]
            if any(not e.writable for e in targets if e.subindex != 0):
                return AdsReturnCode.DEVICE_INVALID_ACCESS
            self.data[start : start + len(data)] = data
            return AdsReturnCode.NO_ERROR
        if not entry.writable:
            return AdsReturnCode.DEVICE_INVALID_ACCESS
        size = (entry.bit_size + 7) // 8
        if entry.is_string:
            if len(data) > size:
                return AdsReturnCode.DEVICE_INVALID_SIZE
            data = data.ljust(size, b"\0")
        elif len(data) != size:
            return AdsReturnCode.DEVICE_INVALID_SIZE
        if entry.bit_offset % 8 == 0 and entry.bit_size % 8 == 0:
            start = entry.bit_offset // 8
            self.data[start : start + size] = data
        else:
            value = int.from_bytes(data, "little")
            if value >> entry.bit_size:
                return AdsReturnCode.DEVICE_INVALID_DATA
            set_bits(self.data, entry.bit_offset, entry.bit_size, value)
        return AdsReturnCode.NO_ERROR

    def value(self, subindex: int) -> int:
        entry = self.entries[subindex]
        return get_bits(self.data, entry.bit_offset, entry.bit_size)


class CoeDictionary:
    """All objects of one slave, ready for SDO requests."""

    def __init__(self, objects: Iterable[CoeObjectStore]) -> None:
        self.objects = {obj.index: obj for obj in objects}

    @classmethod
    def from_terminal(cls, objects: Iterable[CoeObject]) -> CoeDictionary:
        return cls(_store(obj) for obj in objects)

    def __len__(self) -> int:
        return len(self.objects)

    def read(self, offset: int, length: int) -> tuple[int, bytes]:
        index, subindex, complete = split_offset(offset)
        obj = self.objects.get(index)
        if obj is None:
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        result, data = obj.read(subindex, complete)
        if result:
            return result, b""
        return fit(data, length)

    def write(self, offset: int, data: bytes) -> int:
        index, subindex, complete = split_offset(offset)
        obj = self.objects.get(index)
        if obj is None:
            return AdsReturnCode.DEVICE_INVALID_OFFSET
        return obj.write(subindex, data, complete)

    def set_identity(self, identity: SlaveIdentity) -> None:
        """Make 0x1018 report the identity the slave really has (sub-indices
        1-4: vendor, product code, revision, serial number)."""
        obj = self.objects.get(IDENTITY_INDEX)
        if obj is None:
            obj = _record(IDENTITY_INDEX, [(1, 32), (2, 32), (3, 32), (4, 32)])
            self.objects[IDENTITY_INDEX] = obj
        for subindex, value in enumerate(astuple(identity), start=1):
            entry = obj.entries.get(subindex)
            if entry is not None:
                set_bits(obj.data, entry.bit_offset, entry.bit_size, value)


def split_offset(offset: int) -> tuple[int, int, bool]:
    """(index, subindex, complete access) of a 0xF302 index offset."""
    return offset >> 16, offset & 0xFF, bool(offset & COE_COMPLETE_ACCESS_FLAG)


def _record(index: int, subs: list[tuple[int, int]]) -> CoeObjectStore:
    """A record with sub-index 0 (count) and the given (subindex, bits)."""
    entries = {0: CoeEntry(0, 0, 8, True, False)}
    offset = 16
    for subindex, bits in subs:
        entries[subindex] = CoeEntry(subindex, offset, bits, True, False)
        offset += bits
    data = bytearray((offset + 7) // 8)
    data[0] = max(s for s, _ in subs)
    return CoeObjectStore(index, data, entries)


def _store(obj: CoeObject) -> CoeObjectStore:
    if not obj.sub_items:
        entry = CoeEntry(
            0,
            0,
            obj.bit_size,
            obj.access != "wo",
            obj.access in {"rw", "wo"},
            is_string=_is_string(obj.type_name),
        )
        data = bytearray((obj.bit_size + 7) // 8)
        _fill(data, 0, obj.bit_size, obj.default_data)
        return CoeObjectStore(obj.index, data, {0: entry})
    items = sorted(obj.sub_items, key=lambda s: s.subindex)
    offsets = [item.bit_offset for item in items]
    if len(set(offsets)) != len(offsets):
        offsets = _sequential([item.bit_size for item in items])
    entries: dict[int, CoeEntry] = {}
    end = 0
    for item, offset in zip(items, offsets, strict=True):
        access = obj.access_of(item)
        entries[item.subindex] = CoeEntry(
            item.subindex,
            offset,
            item.bit_size,
            access != "wo",
            access in {"rw", "wo"},
            is_string=_is_string(item.type_name),
        )
        end = max(end, offset + item.bit_size)
    size = max((obj.bit_size + 7) // 8, (end + 7) // 8)
    data = bytearray(size)
    for item, offset in zip(items, offsets, strict=True):
        _fill(data, offset, item.bit_size, item.default_data)
    if 0 not in entries and all(entry.bit_offset >= 8 for entry in entries.values()):
        # The ESI lists a record's sub-indices from 1; sub-index 0 (u8) holds
        # the highest one, read-only, in the record's first byte.
        entries[0] = CoeEntry(0, 0, 8, True, False)
        set_bits(data, 0, 8, max(entries))
    elif 0 in entries and not any(
        item.default_data for item in items if item.subindex == 0
    ):
        set_bits(data, entries[0].bit_offset, 8, max(entries))
    return CoeObjectStore(obj.index, data, entries)


def _sequential(sizes: list[int]) -> list[int]:
    """ESI-style offsets when the file gave none: sub-index 0 then 16-bit
    aligned, bit fields packed."""
    offsets: list[int] = []
    position = 0
    for size in sizes:
        if size >= 8 and position % 8:
            position += 8 - position % 8
        offsets.append(position)
        position += size
        if len(offsets) == 1:
            position = 16
    return offsets


def _fill(data: bytearray, bit_offset: int, bit_size: int, default: str | None) -> None:
    if not default or bit_size == 0:
        return
    try:
        raw = bytes.fromhex(default)
    except ValueError:
        return
    size = (bit_size + 7) // 8
    raw = raw[:size].ljust(size, b"\0")
    if bit_offset % 8 == 0 and bit_size % 8 == 0:
        start = bit_offset // 8
        data[start : start + size] = raw
    else:
        value = int.from_bytes(raw, "little") & ((1 << bit_size) - 1)
        set_bits(data, bit_offset, bit_size, value)


def _is_string(type_name: str) -> bool:
    upper = type_name.upper()
    return upper.startswith(("STRING", "VISIBLE_STRING", "OCTET_STRING"))


__all__ = ["CoeDictionary", "CoeEntry", "CoeObjectStore", "split_offset"]
