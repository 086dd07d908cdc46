"""The two process images of a device and typed access to them.

Byte groups read and write bytes at a byte offset. Bit groups address single
bits (offset = byte * 8 + bit) and move one byte per bit (0 or 1), which is
how a BIT symbol of size 1 reads (pyads' 1-byte BOOL).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Final

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.twincat.layout import INPUTS, ImageArea
from fastcs_ethercat.twincat.tctypes import TcType

_BITS: Final = (b"\x00", b"\x01")


def read_slice(buffer: bytearray, offset: int, length: int) -> tuple[int, bytes]:
    """`length` bytes from `offset`: a read past the end is refused whole
    (0x703 when it starts past the end, 0x705 when it runs over it)."""
    end = offset + length
    if end > len(buffer):
        if offset > len(buffer):
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        return AdsReturnCode.DEVICE_INVALID_SIZE, b""
    return AdsReturnCode.NO_ERROR, bytes(buffer[offset:end])


def read_bits(buffer: bytearray, bit_offset: int, count: int) -> tuple[int, bytes]:
    """`count` bits from `bit_offset`, one byte (0 or 1) each, refused past
    the end like `read_slice`."""
    size = 8 * len(buffer)
    if bit_offset + count > size:
        if bit_offset > size:
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        return AdsReturnCode.DEVICE_INVALID_SIZE, b""
    if count == 1:
        return AdsReturnCode.NO_ERROR, _BITS[
            buffer[bit_offset >> 3] >> (bit_offset & 7) & 1
        ]
    return AdsReturnCode.NO_ERROR, bytes(
        (buffer[(bit_offset + i) >> 3] >> ((bit_offset + i) & 7)) & 1
        for i in range(count)
    )


class ProcessImage:
    """Input and output image of one device, as plain bytearrays."""

    __slots__ = ("inputs", "outputs")

    def __init__(self, input_size: int, output_size: int) -> None:
        self.inputs = bytearray(input_size)
        self.outputs = bytearray(output_size)

    def buffer(self, area: ImageArea) -> bytearray:
        return self.inputs if area is INPUTS else self.outputs

    # -- raw access by the ADS groups ------------------------------------------

    def read_bytes(
        self, area: ImageArea, offset: int, length: int
    ) -> tuple[int, bytes]:
        return read_slice(self.buffer(area), offset, length)

    def write_bytes(self, area: ImageArea, offset: int, data: bytes) -> int:
        buffer = self.buffer(area)
        if offset > len(buffer):
            return AdsReturnCode.DEVICE_INVALID_OFFSET
        if offset + len(data) > len(buffer):
            return AdsReturnCode.DEVICE_INVALID_SIZE
        buffer[offset : offset + len(data)] = data
        return AdsReturnCode.NO_ERROR

    def read_bit_bytes(
        self, area: ImageArea, bit_offset: int, count: int
    ) -> tuple[int, bytes]:
        """`count` bits from `bit_offset`, one byte (0 or 1) each."""
        return read_bits(self.buffer(area), bit_offset, count)

    def write_bit_bytes(self, area: ImageArea, bit_offset: int, data: bytes) -> int:
        """Set one bit per byte of `data` (non-zero = 1) from `bit_offset`."""
        buffer = self.buffer(area)
        if bit_offset > 8 * len(buffer):
            return AdsReturnCode.DEVICE_INVALID_OFFSET
        if bit_offset + len(data) > 8 * len(buffer):
            return AdsReturnCode.DEVICE_INVALID_SIZE
        for i, byte in enumerate(data):
            set_bits(buffer, bit_offset + i, 1, 1 if byte else 0)
        return AdsReturnCode.NO_ERROR

    # -- typed access ------------------------------------------------------------

    def read_raw(self, area: ImageArea, bit_address: int, kind: TcType) -> bytes:
        """A value's bytes as a client reads them (a bit field: one byte)."""
        buffer = self.buffer(area)
        if kind.is_bit:
            return bytes([get_bits(buffer, bit_address, kind.bit_size)])
        return raw_bytes(buffer, bit_address, kind.bit_size)

    def write_raw(
        self, area: ImageArea, bit_address: int, kind: TcType, data: bytes
    ) -> None:
        """Store a value's bytes as a client writes them."""
        buffer = self.buffer(area)
        if kind.is_bit:
            set_bits(buffer, bit_address, kind.bit_size, data[0] if data else 0)
            return
        put_raw_bytes(buffer, bit_address, kind.bit_size, data)

    def get_value(self, area: ImageArea, bit_address: int, kind: TcType) -> Any:
        return decode_value(self.buffer(area), bit_address, kind)

    def set_value(
        self, area: ImageArea, bit_address: int, kind: TcType, value: Any
    ) -> None:
        encode_value(self.buffer(area), bit_address, kind, value)


def get_bits(buffer: bytearray | bytes, bit_address: int, count: int) -> int:
    """`count` bits from `bit_address` as an unsigned int (LSB first)."""
    first = bit_address >> 3
    last = (bit_address + count - 1) >> 3
    chunk = int.from_bytes(buffer[first : last + 1], "little")
    return (chunk >> (bit_address & 7)) & ((1 << count) - 1)


def set_bits(buffer: bytearray, bit_address: int, count: int, value: int) -> None:
    """Store the low `count` bits of `value` at `bit_address`."""
    first = bit_address >> 3
    last = (bit_address + count - 1) >> 3
    width = last - first + 1
    chunk = int.from_bytes(buffer[first : last + 1], "little")
    shift = bit_address & 7
    mask = ((1 << count) - 1) << shift
    chunk = (chunk & ~mask) | ((value << shift) & mask)
    buffer[first : last + 1] = chunk.to_bytes(width, "little")


def raw_bytes(buffer: bytearray | bytes, bit_address: int, bit_size: int) -> bytes:
    """Bytes of a field (byte-aligned fields are sliced, others shifted out)."""
    size = (bit_size + 7) // 8
    if bit_address & 7 == 0:
        start = bit_address >> 3
        data = bytes(buffer[start : start + size])
        if bit_size & 7:
            data = data[:-1] + bytes([data[-1] & ((1 << (bit_size & 7)) - 1)])
        return data
    return get_bits(buffer, bit_address, bit_size).to_bytes(size, "little")


def put_raw_bytes(
    buffer: bytearray, bit_address: int, bit_size: int, data: bytes
) -> None:
    size = (bit_size + 7) // 8
    if len(data) != size:
        raise AdsCodecError(
            f"a {bit_size}-bit field takes {size} bytes, got {len(data)}",
            AdsReturnCode.DEVICE_INVALID_SIZE,
        )
    if bit_address & 7 == 0 and bit_size & 7 == 0:
        start = bit_address >> 3
        buffer[start : start + size] = data
        return
    set_bits(buffer, bit_address, bit_size, int.from_bytes(data, "little"))


def decode_value(buffer: bytearray | bytes, bit_address: int, kind: TcType) -> Any:
    """The Python value of a field: bool/int/float, dict for a structure,
    list for an array."""
    if kind.members:
        return {
            member.name: decode_value(
                buffer, bit_address + member.bit_offset, member.type
            )
            for member in kind.members
        }
    if kind.element is not None:
        step = kind.element.byte_size * 8
        return [
            decode_value(buffer, bit_address + i * step, kind.element)
            for i in range(kind.count)
        ]
    scalar = kind.scalar
    assert scalar is not None
    if kind.is_bit:
        bits = get_bits(buffer, bit_address, kind.bit_size)
        return bool(bits) if kind.bit_size == 1 else bits
    return scalar.unpack(raw_bytes(buffer, bit_address, kind.bit_size))


def encode_value(buffer: bytearray, bit_address: int, kind: TcType, value: Any) -> None:
    """Store a Python value (as `decode_value` returns it) in a field; a
    structure takes a mapping of some or all of its members."""
    if kind.members:
        if not isinstance(value, Mapping):
            raise AdsCodecError(
                f"{kind.name} is a structure: give a mapping of its members",
                AdsReturnCode.DEVICE_INVALID_DATA,
            )
        for name, item in value.items():
            member = kind.member(str(name))
            if member is None:
                raise AdsCodecError(
                    f"{kind.name} has no member {name!r}",
                    AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND,
                )
            encode_value(buffer, bit_address + member.bit_offset, member.type, item)
        return
    if kind.element is not None:
        if not isinstance(value, Sequence) or len(value) != kind.count:
            raise AdsCodecError(
                f"{kind.name} needs {kind.count} elements",
                AdsReturnCode.DEVICE_INVALID_DATA,
            )
        step = kind.element.byte_size * 8
        for i, item in enumerate(value):
            encode_value(buffer, bit_address + i * step, kind.element, item)
        return
    scalar = kind.scalar
    assert scalar is not None
    if kind.is_bit:
        number = int(value)
        if not 0 <= number < (1 << kind.bit_size):
            raise AdsCodecError(
                f"{value!r} does not fit {kind.name}", AdsReturnCode.DEVICE_INVALID_DATA
            )
        set_bits(buffer, bit_address, kind.bit_size, number)
        return
    put_raw_bytes(buffer, bit_address, kind.bit_size, scalar.pack(value))


__all__ = [
    "ProcessImage",
    "decode_value",
    "encode_value",
    "get_bits",
    "put_raw_bytes",
    "raw_bytes",
    "set_bits",
]
