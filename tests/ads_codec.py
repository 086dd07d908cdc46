"""Halves of the ADS codec only the tests need: decoders of what the
package encodes (and encoders of what it decodes), to check the other half
against known bytes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

from fastcs_ethercat.ads.commands import FILETIME_TICKS_PER_SECOND, FILETIME_UNIX_EPOCH
from fastcs_ethercat.ads.constants import (
    COE_COMPLETE_ACCESS_FLAG,
    AdsDataType,
    AdsReturnCode,
    DataTypeFlag,
)
from fastcs_ethercat.ads.datatypes import AdsDataTypeEntry
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import (
    AMS_TCP_HEADER_SIZE,
    AmsPacket,
    decode_ams,
    decode_tcp_header,
)
from fastcs_ethercat.ads.wire import ByteReader, decode_text

FILETIME_START = datetime(1601, 1, 1, tzinfo=UTC)


def decode_packet(frame: bytes | bytearray | memoryview) -> AmsPacket:
    """Decode exactly one whole AMS/TCP frame."""
    if len(frame) < AMS_TCP_HEADER_SIZE:
        raise AdsCodecError(
            f"AMS/TCP frame needs {AMS_TCP_HEADER_SIZE} header bytes, got {len(frame)}",
            AdsReturnCode.INVALID_AMS_LENGTH,
        )
    length = decode_tcp_header(frame[:AMS_TCP_HEADER_SIZE])
    body = frame[AMS_TCP_HEADER_SIZE:]
    if len(body) != length:
        raise AdsCodecError(
            f"AMS/TCP header says {length} bytes follow, frame has {len(body)}",
            AdsReturnCode.INVALID_AMS_LENGTH,
        )
    return decode_ams(body)


def decode_symbol_name(data: bytes | bytearray | memoryview) -> str:
    """The name in a by-name request's write data: text up to the first NUL.

    pyads encodes the name as UTF-8 while TwinCAT names are Windows-1252; the
    two agree for ASCII names, which is what the I/O symbol table holds.
    """
    return decode_text(bytes(data).split(b"\0", 1)[0])


def decode_crc_totals(raw: bytes | bytearray | memoryview) -> tuple[int, ...]:
    if len(raw) % 4:
        raise AdsCodecError(
            f"CRC totals: length {len(raw)} is not a multiple of 4",
            AdsReturnCode.DEVICE_INVALID_SIZE,
        )
    reader = ByteReader(raw, "CRC totals")
    return tuple(reader.u32() for _ in range(len(raw) // 4))


def coe_index_offset(index: int, subindex: int, complete_access: bool = False) -> int:
    """Index offset of a CoE SDO request: index << 16 | subindex (| 0x100)."""
    flag = COE_COMPLETE_ACCESS_FLAG if complete_access else 0
    return (index << 16) | flag | (subindex & 0xFF)


@dataclass(frozen=True, slots=True)
class MemberSpec:
    """Input to `layout_structure`: one member's name, type and byte size."""

    name: str
    type_name: str
    data_type: AdsDataType | int
    size: int


def layout_structure(
    name: str,
    members: Sequence[MemberSpec],
    pack: int = 1,
    comment: str = "",
) -> AdsDataTypeEntry:
    """A structure entry with members placed one after another.

    Offsets align to min(member size, `pack`) bytes; pack=1 is the packed
    layout of TwinCAT's I/O process-image types (e.g. Status u16 at +0,
    Value INT at +2).
    """
    offset = 0
    items: list[AdsDataTypeEntry] = []
    largest = 1
    for member in members:
        alignment = max(1, min(member.size, pack))
        largest = max(largest, alignment)
        offset = -(-offset // alignment) * alignment
        items.append(
            AdsDataTypeEntry(
                name=member.name,
                type_name=member.type_name,
                size=member.size,
                data_type=member.data_type,
                flags=DataTypeFlag.DATA_ITEM,
                offset=offset,
            )
        )
        offset += member.size
    size = -(-offset // largest) * largest
    return AdsDataTypeEntry(
        name=name,
        type_name="",
        size=size,
        data_type=AdsDataType.BIGTYPE,
        flags=DataTypeFlag.DATA_TYPE,
        comment=comment,
        sub_items=tuple(items),
    )


def filetime_to_unix_ns(filetime: int) -> int:
    """Nanoseconds since the Unix epoch for FILETIME ticks."""
    return (filetime - FILETIME_UNIX_EPOCH) * 100


def filetime_from_datetime(moment: datetime) -> int:
    """FILETIME ticks of an aware datetime (a naive one is taken as UTC)."""
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    delta = moment - FILETIME_START
    return (
        delta.days * 86_400 * FILETIME_TICKS_PER_SECOND
        + delta.seconds * FILETIME_TICKS_PER_SECOND
        + delta.microseconds * 10
    )
