"""Answers of the TwinCAT I/O server and the EtherCAT master (facts section 6).

I/O server (system NetId, port 300): group 0x5000 offset 2 device count u32,
offset 1 device ids (u16 count + u16 each); group 0x5000 + id offset 1 name,
offset 5 the device's NetId, offset 7 device type u16.

EtherCAT master (device NetId, port 0xFFFF): 0x03/0x100 master state u16,
0x06 slave count u16, 0x07 slave addresses u16 x n, 0x09 (AL state u8, link
state u8) per slave, 0x0C frame counters 5 x u32, 0x11 identity 4 x u32,
0x12 CRC counters (offset = slave address: 4 x u32, one per port; offset 0:
one u32 per slave, its ports added).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import Final, Self

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.wire import (
    ByteReader,
    FixedRecord,
    decode_c_string,
    encode_text,
    exactly,
    pack,
)

DEVICE_NAME_MAX: Final = 255
SLAVE_INFO_INDEX: Final = 0x8000
"""Master CoE: object 0x8000 + n describes slave n (sub 2 type, sub 3 name)."""
SLAVE_TYPE_SUBINDEX: Final = 2
SLAVE_NAME_SUBINDEX: Final = 3


class AlState(IntEnum):
    """EtherCAT application-layer state (low nibble of the state byte)."""

    INIT = 1
    PREOP = 2
    BOOT = 3
    SAFEOP = 4
    OP = 8


class AlStateFlag(IntFlag):
    """High-nibble flags of a slave's state byte."""

    ERROR = 0x10
    INVALID_VPRS = 0x20
    """Invalid vendor id, product code, revision or serial number."""
    INIT_COMMAND_ERROR = 0x40
    DISABLED = 0x80


class LinkState(IntFlag):
    """A slave's link-state byte (0 = all fine)."""

    NOT_PRESENT = 0x01
    NO_COMMUNICATION = 0x02
    MISSING_LINK = 0x04
    ADDITIONAL_LINK = 0x08
    PORT_A = 0x10
    PORT_B = 0x20
    PORT_C = 0x40
    PORT_D = 0x80

    def own_fault(self) -> bool:
        """Whether the slave itself is cut off, judged per port: not present,
        or no link (or no communication) on its incoming port A or on no port
        named. The same flags on port B, C or D are about the neighbour
        beyond that port (the slave before a lost one reports MISSING_LINK on
        B), an additional link is a topology note: neither is this slave's."""
        if self & LinkState.NOT_PRESENT:
            return True
        if not self & (LinkState.NO_COMMUNICATION | LinkState.MISSING_LINK):
            return False
        ports = self & (
            LinkState.PORT_A | LinkState.PORT_B | LinkState.PORT_C | LinkState.PORT_D
        )
        return not ports or bool(ports & LinkState.PORT_A)


def _u16_array(raw: bytes | bytearray | memoryview, what: str) -> tuple[int, ...]:
    if len(raw) % 2:
        raise AdsCodecError(
            f"{what}: odd length {len(raw)} for u16 values",
            AdsReturnCode.DEVICE_INVALID_SIZE,
        )
    reader = ByteReader(raw, what)
    return tuple(reader.u16() for _ in range(len(raw) // 2))


# -- I/O server -------------------------------------------------------------


def encode_device_count(count: int) -> bytes:
    return pack("<I", count)


def decode_device_count(raw: bytes | bytearray | memoryview) -> int:
    return exactly(raw, 4, "device count").u32()


def encode_device_ids(device_ids: Sequence[int]) -> bytes:
    """u16 count, then one u16 id per device."""
    return pack(f"<H{len(device_ids)}H", len(device_ids), *device_ids)


def decode_device_ids(raw: bytes | bytearray | memoryview) -> tuple[int, ...]:
    """Ids after the u16 count; a buffer longer than the count says (a client
    reading with a generous length) is accepted, a shorter one is not."""
    reader = ByteReader(raw, "device ids")
    count = reader.u16()
    return tuple(reader.u16() for _ in range(count))


def encode_device_name(name: str) -> bytes:
    """The device name, NUL-terminated (at most 255 characters)."""
    raw = encode_text(name)
    if len(raw) > DEVICE_NAME_MAX:
        raise AdsCodecError(
            f"device name longer than {DEVICE_NAME_MAX} bytes",
            AdsReturnCode.DEVICE_INVALID_DATA,
        )
    return raw + b"\0"


def decode_device_name(raw: bytes | bytearray | memoryview) -> str:
    """The name up to its first NUL (or the whole buffer without one)."""
    return decode_c_string(bytes(raw))


def encode_device_netid(netid: AmsNetId) -> bytes:
    return netid.to_bytes()


def decode_device_netid(raw: bytes | bytearray | memoryview) -> AmsNetId:
    return AmsNetId.from_bytes(raw)


def encode_device_type(device_type: int) -> bytes:
    return pack("<H", device_type)


def decode_device_type(raw: bytes | bytearray | memoryview) -> int:
    return exactly(raw, 2, "device type").u16()


# -- EtherCAT master --------------------------------------------------------


def encode_master_state(state: int) -> bytes:
    return pack("<H", state)


def decode_master_state(raw: bytes | bytearray | memoryview) -> int:
    return exactly(raw, 2, "master state").u16()


def encode_slave_count(count: int) -> bytes:
    return pack("<H", count)


def decode_slave_count(raw: bytes | bytearray | memoryview) -> int:
    return exactly(raw, 2, "slave count").u16()


def encode_slave_addresses(addresses: Sequence[int]) -> bytes:
    return pack(f"<{len(addresses)}H", *addresses)


def decode_slave_addresses(raw: bytes | bytearray | memoryview) -> tuple[int, ...]:
    return _u16_array(raw, "slave addresses")


@dataclass(frozen=True, slots=True)
class SlaveState(FixedRecord):
    """A slave's raw state byte and link-state byte."""

    layout = struct.Struct("<BB")
    state: int
    link: int = 0

    @classmethod
    def of(
        cls,
        al_state: AlState,
        flags: AlStateFlag | int = 0,
        link: LinkState | int = 0,
    ) -> Self:
        return cls(int(al_state) | int(flags), int(link))

    @property
    def al_state(self) -> AlState | int:
        """The low nibble: INIT, PREOP, BOOT, SAFEOP or OP."""
        try:
            return AlState(self.state & 0x0F)
        except ValueError:
            return self.state & 0x0F

    @property
    def flags(self) -> AlStateFlag:
        return AlStateFlag(self.state & 0xF0)

    @property
    def link_state(self) -> LinkState:
        return LinkState(self.link)


def encode_slave_states(states: Sequence[SlaveState]) -> bytes:
    """Group 0x09 offset 0: one (state, link) pair per slave, in chain order."""
    return b"".join(state.encode() for state in states)


def decode_slave_states(raw: bytes | bytearray | memoryview) -> tuple[SlaveState, ...]:
    data = bytes(raw)
    if len(data) % 2:
        raise AdsCodecError(
            f"slave states: odd length {len(data)}", AdsReturnCode.DEVICE_INVALID_SIZE
        )
    return tuple(SlaveState(data[i], data[i + 1]) for i in range(0, len(data), 2))


@dataclass(frozen=True, slots=True)
class SlaveIdentity(FixedRecord):
    """CANopen identity (object 0x1018) of a slave: 4 x u32."""

    layout = struct.Struct("<4I")
    vendor_id: int
    product_code: int
    revision: int
    serial_number: int = 0

    def __str__(self) -> str:
        """`0x2/0xBB83052/0x110000`: vendor id, product code and revision,
        as logs and descriptions name a slave that no YAML describes."""
        return f"0x{self.vendor_id:X}/0x{self.product_code:X}/0x{self.revision:X}"


@dataclass(frozen=True, slots=True)
class FrameCounters(FixedRecord):
    """Group 0x0C: five u32 counters of the master's frames.

    Field meanings follow catio's reading (a time base, then cyclic and
    acyclic frames sent and lost) and are unconfirmed.
    """

    layout = struct.Struct("<5I")
    time: int = 0
    cyclic_sent: int = 0
    cyclic_lost: int = 0
    acyclic_sent: int = 0
    acyclic_lost: int = 0


@dataclass(frozen=True, slots=True)
class CrcCounters(FixedRecord):
    """Group 0x12, offset = slave address: CRC error counters per port."""

    layout = struct.Struct("<4I")
    port_a: int = 0
    port_b: int = 0
    port_c: int = 0
    port_d: int = 0

    @property
    def total(self) -> int:
        """The four ports added, as group 0x12 offset 0 reports each slave."""
        return (self.port_a + self.port_b + self.port_c + self.port_d) & 0xFFFF_FFFF


def encode_crc_totals(totals: Sequence[int]) -> bytes:
    """Group 0x12 offset 0: per slave in bus order, its ports' CRC error
    counters added, u32 each (Beckhoff FB_EcGetAllSlaveCrcErrors)."""
    return pack(f"<{len(totals)}I", *totals)
