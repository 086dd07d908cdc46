"""I/O server and EtherCAT master answers: layouts, round trips, state enums."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.ethercat import (
    AlState,
    AlStateFlag,
    CrcCounters,
    FrameCounters,
    LinkState,
    SlaveIdentity,
    SlaveState,
    decode_device_count,
    decode_device_ids,
    decode_device_name,
    decode_device_netid,
    decode_device_type,
    decode_master_state,
    decode_slave_addresses,
    decode_slave_count,
    decode_slave_states,
    encode_device_count,
    encode_device_ids,
    encode_device_name,
    encode_device_netid,
    encode_device_type,
    encode_master_state,
    encode_slave_addresses,
    encode_slave_count,
    encode_slave_states,
)
from fastcs_ethercat.ads.netid import AmsNetId

u32 = st.integers(0, 0xFFFF_FFFF)
u16 = st.integers(0, 0xFFFF)


def test_io_server_layouts_by_hand() -> None:
    assert encode_device_count(2) == b"\x02\x00\x00\x00"
    assert encode_device_ids([1, 3]) == struct.pack("<3H", 2, 1, 3)
    assert decode_device_ids(struct.pack("<3H", 2, 1, 3) + b"\0" * 10) == (1, 3)
    assert encode_device_name("Device 1 (EtherCAT)") == b"Device 1 (EtherCAT)\0"
    assert decode_device_name(b"Device 1 (EtherCAT)\0\0\0") == "Device 1 (EtherCAT)"
    netid = AmsNetId.parse("5.12.34.56.2.1")
    assert decode_device_netid(encode_device_netid(netid)) == netid
    assert encode_device_type(94) == b"\x5e\x00"
    assert decode_device_type(b"\x5e\x00") == 94
    assert decode_device_count(encode_device_count(7)) == 7


def test_master_layouts_by_hand() -> None:
    assert encode_master_state(8) == b"\x08\x00"
    assert decode_master_state(b"\x08\x00") == 8
    assert encode_slave_count(3) == b"\x03\x00"
    assert decode_slave_count(b"\x03\x00") == 3
    assert encode_slave_addresses([1001, 1002]) == struct.pack("<2H", 1001, 1002)
    assert decode_slave_addresses(struct.pack("<2H", 1001, 1002)) == (1001, 1002)
    op = SlaveState.of(AlState.OP)
    broken = SlaveState.of(
        AlState.SAFEOP, AlStateFlag.ERROR, LinkState.MISSING_LINK | LinkState.PORT_B
    )
    assert encode_slave_states([op, broken]) == b"\x08\x00\x14\x24"
    assert decode_slave_states(b"\x08\x00\x14\x24") == (op, broken)
    assert broken.al_state == AlState.SAFEOP
    assert broken.flags == AlStateFlag.ERROR
    assert broken.link_state == LinkState.MISSING_LINK | LinkState.PORT_B
    assert SlaveState.decode(b"\x08\x00") == op
    identity = SlaveIdentity(2, 0x0C203052, 0x00100000, 0)
    assert identity.encode() == struct.pack("<4I", 2, 0x0C203052, 0x00100000, 0)
    assert SlaveIdentity.decode(identity.encode()) == identity
    assert FrameCounters.decode(struct.pack("<5I", 1, 2, 3, 4, 5)) == FrameCounters(
        1, 2, 3, 4, 5
    )
    assert CrcCounters(1, 0, 0, 0).encode() == struct.pack("<4I", 1, 0, 0, 0)


def test_unknown_al_state_nibble_is_kept() -> None:
    assert SlaveState(0x05).al_state == 5


@given(st.lists(u16, max_size=20))
def test_u16_lists_round_trip(values: list[int]) -> None:
    assert decode_slave_addresses(encode_slave_addresses(values)) == tuple(values)
    assert decode_device_ids(encode_device_ids(values)) == tuple(values)


@given(
    st.builds(SlaveIdentity, u32, u32, u32, u32),
    st.builds(FrameCounters, u32, u32, u32, u32, u32),
)
def test_structures_round_trip(
    identity: SlaveIdentity, counters: FrameCounters
) -> None:
    assert SlaveIdentity.decode(identity.encode()) == identity
    assert FrameCounters.decode(counters.encode()) == counters


@pytest.mark.parametrize(
    ("decode", "raw"),
    [
        (decode_device_count, b"\0\0\0"),
        (decode_device_type, b"\0"),
        (decode_master_state, b"\0\0\0"),
        (decode_slave_count, b""),
        (decode_slave_addresses, b"\0\0\0"),
        (decode_slave_states, b"\0"),
        (decode_device_ids, struct.pack("<2H", 2, 1)),
        (SlaveIdentity.decode, b"\0" * 15),
        (FrameCounters.decode, b"\0" * 21),
        (CrcCounters.decode, b"\0" * 4),
        (decode_device_netid, b"\0" * 5),
    ],
)
def test_wrong_sizes(decode: object, raw: bytes) -> None:
    with pytest.raises(AdsCodecError):
        decode(raw)  # type: ignore[operator]


def test_out_of_range_encodes() -> None:
    with pytest.raises(AdsCodecError):
        encode_slave_addresses([70000])
    with pytest.raises(AdsCodecError):
        encode_device_name("x" * 256)


@given(st.binary(max_size=24))
def test_decoders_only_raise_codec_errors(raw: bytes) -> None:
    for decode in (
        decode_device_count,
        decode_device_ids,
        decode_device_name,
        decode_device_netid,
        decode_device_type,
        decode_master_state,
        decode_slave_count,
        decode_slave_addresses,
        decode_slave_states,
        SlaveState.decode,
        SlaveIdentity.decode,
        FrameCounters.decode,
        CrcCounters.decode,
    ):
        with contextlib.suppress(AdsCodecError):
            decode(raw)


@pytest.mark.parametrize(
    ("link", "own"),
    [
        (0, False),
        (LinkState.NOT_PRESENT, True),
        (LinkState.MISSING_LINK | LinkState.PORT_B, False),  # the next slave's
        (LinkState.NO_COMMUNICATION | LinkState.PORT_C, False),
        (LinkState.ADDITIONAL_LINK | LinkState.PORT_D, False),
        (LinkState.MISSING_LINK | LinkState.PORT_A, True),  # its own way in
        (LinkState.MISSING_LINK, True),  # no port named: its own
        (LinkState.NO_COMMUNICATION, True),
    ],
)
def test_a_link_fault_is_the_slaves_own_only_on_its_own_port(
    link: int, own: bool
) -> None:
    assert LinkState(link).own_fault() is own
