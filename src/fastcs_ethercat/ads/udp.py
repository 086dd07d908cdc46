"""UDP 48899 packets: target discovery and add-route (facts file section 8).

Layout, little-endian, as pyads 3.6 builds and checks it
(`pyads_ex.adsGetNetIdForPLC`, `pyads_ex.adsAddRouteToPLC`):

    0  magic u32 0x71146603      4  invoke id u32
    8  service u32 (1 discover, 6 add route; | 0x80000000 in a reply)
    12 AMS NetId (6)             18 AMS port u16 (10000, system service)
    20 tag count u32             24 tags: id u16, length u16, data
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Final, Self

from fastcs_ethercat.ads.constants import AdsReturnCode, AmsPort
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.wire import (
    ByteReader,
    decode_c_string,
    encode_text,
    enum_or_int,
    pack,
)

UDP_MAGIC: Final = 0x71146603
UDP_HEADER_SIZE: Final = 24
UDP_RESPONSE_FLAG: Final = 0x8000_0000
MAX_UDP_TAGS: Final = 64
"""A sane cap on the tag count so a corrupt packet cannot ask for millions."""

_HEAD: Final = struct.Struct("<III6sHI")
_TAG: Final = struct.Struct("<HH")


class UdpService(IntEnum):
    """System-service ids of the UDP packets."""

    DISCOVER = 1
    ADD_ROUTE = 6


class UdpTag(IntEnum):
    """Tag ids (pyads' order for add-route: ROUTE_NAME, NETID, USER_NAME,
    PASSWORD, HOST)."""

    STATUS = 0x0001
    """Reply result u32 (add route: 0 = route added)."""
    PASSWORD = 0x0002
    TWINCAT_VERSION = 0x0003
    """Discover reply: major u8, minor u8, build u16."""
    OS_VERSION = 0x0004
    HOST = 0x0005
    """Host name or IP, NUL-terminated."""
    NETID = 0x0007
    ROUTE_NAME = 0x000C
    USER_NAME = 0x000D


@dataclass(frozen=True, slots=True)
class UdpTagValue:
    """One tag: its id and raw data."""

    tag: UdpTag | int
    data: bytes

    @classmethod
    def text(cls, tag: UdpTag | int, value: str) -> Self:
        """A NUL-terminated string tag (as pyads sends its strings)."""
        return cls(tag, encode_text(value) + b"\0")

    def as_text(self) -> str:
        return decode_c_string(self.data)

    def as_u32(self) -> int:
        reader = ByteReader(self.data, f"UDP tag 0x{int(self.tag):04X}")
        value = reader.u32()
        reader.expect_end()
        return value


@dataclass(frozen=True, slots=True)
class UdpPacket:
    """A discovery or add-route request or reply."""

    service: int
    netid: AmsNetId
    tags: tuple[UdpTagValue, ...] = ()
    port: int = AmsPort.SYSTEM_SERVICE
    invoke_id: int = 0

    @property
    def is_reply(self) -> bool:
        return bool(self.service & UDP_RESPONSE_FLAG)

    @property
    def base_service(self) -> int:
        """The service without the reply flag."""
        return self.service & ~UDP_RESPONSE_FLAG

    def tag(self, tag: UdpTag | int) -> UdpTagValue | None:
        """The first tag with this id, if any."""
        return next((t for t in self.tags if t.tag == tag), None)

    def encode(self) -> bytes:
        head = pack(
            _HEAD,
            UDP_MAGIC,
            self.invoke_id,
            self.service,
            self.netid.to_bytes(),
            self.port,
            len(self.tags),
            what="UDP packet field",
        )
        tags = b"".join(
            pack(_TAG, int(t.tag), len(t.data), what="UDP tag") + bytes(t.data)
            for t in self.tags
        )
        return head + tags

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        """Decode a packet; bytes after the last tag are rejected."""
        reader = ByteReader(raw, "UDP packet")
        reader.take(UDP_HEADER_SIZE)
        magic, invoke_id, service, netid, port, tag_count = _HEAD.unpack_from(
            bytes(raw)
        )
        if magic != UDP_MAGIC:
            raise AdsCodecError(
                f"UDP packet magic is 0x{magic:08X}, expected 0x{UDP_MAGIC:08X}",
                AdsReturnCode.DEVICE_INVALID_DATA,
            )
        if tag_count > MAX_UDP_TAGS:
            raise AdsCodecError(
                f"UDP packet claims {tag_count} tags (limit {MAX_UDP_TAGS})",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        tags: list[UdpTagValue] = []
        for _ in range(tag_count):
            tag_id, length = reader.u16(), reader.u16()
            tags.append(UdpTagValue(enum_or_int(UdpTag, tag_id), reader.take(length)))
        reader.expect_end()
        return cls(service, AmsNetId.from_bytes(netid), tuple(tags), port, invoke_id)


# -- the packets pyads sends and expects ------------------------------------


def discover_request(netid: AmsNetId) -> UdpPacket:
    """What pyads' `adsGetNetIdForPLC` sends (it uses 1.1.1.1.1.1)."""
    return UdpPacket(UdpService.DISCOVER, netid)


def discover_reply(
    netid: AmsNetId,
    host_name: str,
    twincat_version: tuple[int, int, int] = (3, 1, 4024),
    invoke_id: int = 0,
) -> UdpPacket:
    """A discovery reply: the target's NetId (all pyads reads), its host name
    and its TwinCAT version as tags."""
    major, minor, build = twincat_version
    version = pack("<BBH", major, minor, build, what="TwinCAT version")
    return UdpPacket(
        UdpService.DISCOVER | UDP_RESPONSE_FLAG,
        netid,
        (
            UdpTagValue.text(UdpTag.HOST, host_name),
            UdpTagValue(UdpTag.TWINCAT_VERSION, version),
        ),
        invoke_id=invoke_id,
    )


def add_route_request(
    sending_netid: AmsNetId,
    route_name: str,
    added_netid: AmsNetId,
    user_name: str,
    password: str,
    host: str,
) -> UdpPacket:
    """The add-route request with pyads' tags in pyads' order."""
    return UdpPacket(
        UdpService.ADD_ROUTE,
        sending_netid,
        (
            UdpTagValue.text(UdpTag.ROUTE_NAME, route_name),
            UdpTagValue(UdpTag.NETID, added_netid.to_bytes()),
            UdpTagValue.text(UdpTag.USER_NAME, user_name),
            UdpTagValue.text(UdpTag.PASSWORD, password),
            UdpTagValue.text(UdpTag.HOST, host),
        ),
    )


def add_route_reply(
    netid: AmsNetId, result: int = AdsReturnCode.NO_ERROR, invoke_id: int = 0
) -> UdpPacket:
    """The 32-byte add-route reply: head plus one STATUS tag (result u32).

    pyads 3.6 accepts it as success only if bytes 26..28 are 04 00 00 (tag
    length 4, result starting with a zero byte); any other result makes pyads
    raise "Unexpected response".
    """
    return UdpPacket(
        UdpService.ADD_ROUTE | UDP_RESPONSE_FLAG,
        netid,
        (UdpTagValue(UdpTag.STATUS, pack("<I", result, what="add-route result")),),
        invoke_id=invoke_id,
    )
