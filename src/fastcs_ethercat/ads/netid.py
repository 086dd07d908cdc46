"""AMS NetIds ("a.b.c.d.e.f", six bytes) and AMS addresses (NetId + port)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Final, Self

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.wire import exactly

NETID_SIZE: Final = 6
AMS_ADDRESS_SIZE: Final = 8
_ADDRESS = struct.Struct("<6sH")


@dataclass(frozen=True, slots=True, order=True)
class AmsNetId:
    """Six bytes naming an ADS router, written as six dotted decimals."""

    octets: tuple[int, int, int, int, int, int]

    def __post_init__(self) -> None:
        if len(self.octets) != NETID_SIZE or not all(
            isinstance(o, int) and 0 <= o <= 255 for o in self.octets
        ):
            raise AdsCodecError(
                f"an AMS NetId is six bytes 0..255, got {self.octets!r}",
                AdsReturnCode.INVALID_AMS_NETID,
            )

    @classmethod
    def parse(cls, text: str) -> Self:
        """Parse "a.b.c.d.e.f" (each part a decimal 0..255)."""
        parts = text.strip().split(".")
        if len(parts) != NETID_SIZE or not all(
            p.isascii() and p.isdigit() for p in parts
        ):
            raise AdsCodecError(
                f"an AMS NetId looks like 5.12.34.56.1.1, got {text!r}",
                AdsReturnCode.INVALID_AMS_NETID,
            )
        a, b, c, d, e, f = (int(p) for p in parts)
        return cls((a, b, c, d, e, f))

    @classmethod
    def from_bytes(cls, raw: bytes | bytearray | memoryview) -> Self:
        """Decode the six wire bytes of a NetId."""
        reader = exactly(
            raw, NETID_SIZE, "an AMS NetId", AdsReturnCode.INVALID_AMS_NETID
        )
        a, b, c, d, e, f = reader.rest()
        return cls((a, b, c, d, e, f))

    @classmethod
    def from_ip(cls, ip: str, tail: tuple[int, int] = (1, 1)) -> Self:
        """The conventional NetId of a host: its IPv4 address plus ".1.1"."""
        return cls.parse(f"{ip}.{tail[0]}.{tail[1]}")

    def to_bytes(self) -> bytes:
        return bytes(self.octets)

    def with_octet(self, index: int, value: int) -> AmsNetId:
        """This NetId with one octet replaced (device NetIds differ in byte 5)."""
        octets = list(self.octets)
        octets[index] = value
        a, b, c, d, e, f = octets
        return AmsNetId((a, b, c, d, e, f))

    def __str__(self) -> str:
        return ".".join(str(o) for o in self.octets)


@dataclass(frozen=True, slots=True, order=True)
class AmsAddress:
    """One ADS endpoint: a NetId and a 16-bit AMS port."""

    netid: AmsNetId
    port: int

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 0xFFFF:
            raise AdsCodecError(
                f"an AMS port is 0..65535, got {self.port}",
                AdsReturnCode.INVALID_AMS_PORT,
            )

    @classmethod
    def parse(cls, text: str) -> Self:
        """Parse "a.b.c.d.e.f:port"."""
        netid, sep, port = text.rpartition(":")
        if not sep or not (port.isascii() and port.strip().isdigit()):
            raise AdsCodecError(
                f"an AMS address looks like 5.12.34.56.1.1:851, got {text!r}",
                AdsReturnCode.INVALID_AMS_PORT,
            )
        return cls(AmsNetId.parse(netid), int(port))

    @classmethod
    def from_bytes(cls, raw: bytes | bytearray | memoryview) -> Self:
        """Decode NetId (6 bytes) + port (u16), as in the AMS header."""
        reader = exactly(
            raw, AMS_ADDRESS_SIZE, "an AMS address", AdsReturnCode.INVALID_AMS_NETID
        )
        return cls(AmsNetId.from_bytes(reader.take(NETID_SIZE)), reader.u16())

    def to_bytes(self) -> bytes:
        return _ADDRESS.pack(self.netid.to_bytes(), self.port)

    def __str__(self) -> str:
        return f"{self.netid}:{self.port}"
