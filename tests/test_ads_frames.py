"""AMS/TCP framing: byte-exact headers, the reassembler, and pyads' own parser."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyads.testserver.handler import AmsResponseData
from pyads.testserver.testserver import AdsClientConnection

from fastcs_ethercat.ads.commands import ReadRequest
from fastcs_ethercat.ads.constants import (
    RESPONSE_FLAGS,
    AdsReturnCode,
    AmsCommand,
    StateFlag,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import (
    AmsPacket,
    FrameReassembler,
    encode_packet,
)
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from tests.ads_codec import decode_packet

TARGET = AmsAddress(AmsNetId.parse("5.12.34.56.1.1"), 27905)
SOURCE = AmsAddress(AmsNetId.parse("192.168.0.10.1.1"), 32905)

# A Read request (group 0xF005, offset 7, length 2) written out by hand from
# the facts file, section 1: AMS/TCP header, then the 32-byte AMS header.
READ_REQUEST_HEX = (
    "0000"
    "2c000000"  # reserved, length 32 + 12
    "050c22380101"
    "016d"  # target NetId, port 27905
    "c0a8000a0101"
    "8980"  # source NetId, port 32905
    "0200"
    "0400"  # command Read, flags ADS command
    "0c000000"
    "00000000"
    "78563412"  # data length, error code, invoke id
    "05f00000"
    "07000000"
    "02000000"  # group, offset, length
)

READ_REQUEST = AmsPacket(
    target=TARGET,
    source=SOURCE,
    command=AmsCommand.READ,
    invoke_id=0x12345678,
    payload=ReadRequest(0xF005, 7, 2).encode(),
)

netids = st.tuples(*[st.integers(0, 255)] * 6).map(AmsNetId)
addresses = st.builds(AmsAddress, netids, st.integers(0, 0xFFFF))
packets = st.builds(
    AmsPacket,
    target=addresses,
    source=addresses,
    command=st.integers(0, 0xFFFF),
    state_flags=st.integers(0, 0xFFFF),
    error_code=st.integers(0, 0xFFFF_FFFF),
    invoke_id=st.integers(0, 0xFFFF_FFFF),
    payload=st.binary(max_size=64),
)


def test_read_request_matches_hand_written_bytes() -> None:
    assert encode_packet(READ_REQUEST).hex() == READ_REQUEST_HEX
    assert decode_packet(bytes.fromhex(READ_REQUEST_HEX)) == READ_REQUEST


def test_response_swaps_addresses_and_keeps_command_and_invoke_id() -> None:
    response = READ_REQUEST.response(b"\x00" * 8)
    assert response.target == SOURCE
    assert response.source == TARGET
    assert response.command == AmsCommand.READ
    assert response.invoke_id == READ_REQUEST.invoke_id
    assert response.state_flags == RESPONSE_FLAGS == 0x0005
    assert response.is_response and not READ_REQUEST.is_response


def test_pyads_testserver_parses_our_request() -> None:
    """pyads' own test server slices AMS fields at the same offsets."""
    parsed = AdsClientConnection.construct_request(encode_packet(READ_REQUEST))
    header = parsed.ams_header
    assert header.target_net_id == TARGET.netid.to_bytes()
    assert struct.unpack("<H", header.target_port)[0] == TARGET.port
    assert header.source_net_id == SOURCE.netid.to_bytes()
    assert struct.unpack("<H", header.source_port)[0] == SOURCE.port
    assert struct.unpack("<H", header.command_id)[0] == AmsCommand.READ
    assert struct.unpack("<H", header.state_flags)[0] == StateFlag.ADS_COMMAND
    assert struct.unpack("<I", header.length)[0] == 12
    assert struct.unpack("<I", header.invoke_id)[0] == 0x12345678
    assert header.data == READ_REQUEST.payload


def test_we_parse_pyads_testserver_response() -> None:
    """A response framed by pyads' test server decodes as its request's answer."""
    request = AdsClientConnection.construct_request(encode_packet(READ_REQUEST))
    raw = AdsClientConnection.construct_response(
        AmsResponseData(
            struct.pack("<H", RESPONSE_FLAGS),
            struct.pack("<I", 0),
            b"\x00\x00\x00\x00\x02\x00\x00\x00\x34\x12",
        ),
        request,
    )
    packet = decode_packet(raw)
    assert packet == READ_REQUEST.response(b"\x00\x00\x00\x00\x02\x00\x00\x00\x34\x12")


@given(packets)
def test_packet_round_trip(packet: AmsPacket) -> None:
    assert decode_packet(encode_packet(packet)) == packet


def test_reassembler_one_byte_chunks() -> None:
    stream = encode_packet(READ_REQUEST) * 3
    reassembler = FrameReassembler()
    received: list[AmsPacket] = []
    for i in range(len(stream)):
        received += reassembler.feed(stream[i : i + 1])
    assert received == [READ_REQUEST] * 3
    assert reassembler.buffered == 0


def test_reassembler_coalesced_frames_with_a_partial_tail() -> None:
    one = encode_packet(READ_REQUEST)
    reassembler = FrameReassembler()
    assert reassembler.feed(one * 2 + one[:10]) == [READ_REQUEST] * 2
    assert reassembler.buffered == 10
    assert reassembler.feed(one[10:]) == [READ_REQUEST]
    assert reassembler.buffered == 0


@given(st.lists(packets, max_size=5), st.lists(st.integers(1, 50), max_size=20))
def test_reassembler_any_split_gives_back_the_packets(
    sent: list[AmsPacket], cuts: list[int]
) -> None:
    stream = b"".join(encode_packet(p) for p in sent)
    reassembler = FrameReassembler()
    received: list[AmsPacket] = []
    position = 0
    for cut in [*cuts, len(stream)]:
        received += reassembler.feed(stream[position : position + cut])
        position += cut
    received += reassembler.feed(stream[position:])
    assert received == sent


def test_reassembler_rejects_oversized_frame_from_its_header_alone() -> None:
    reassembler = FrameReassembler(max_frame_size=1024)
    with pytest.raises(AdsCodecError) as caught:
        reassembler.feed(struct.pack("<HI", 0, 1025))
    assert caught.value.return_code == AdsReturnCode.INVALID_AMS_LENGTH
    with pytest.raises(AdsCodecError):  # stays broken: framing is lost
        reassembler.feed(encode_packet(READ_REQUEST))


def test_reassembler_rejects_length_mismatch_with_ams_header() -> None:
    frame = bytearray(encode_packet(READ_REQUEST))
    frame[26:30] = struct.pack("<I", 11)  # AMS data length 11, 12 bytes carried
    with pytest.raises(AdsCodecError, match="says 11 data bytes"):
        FrameReassembler().feed(bytes(frame))


def test_reassembler_rejects_frame_shorter_than_ams_header() -> None:
    with pytest.raises(AdsCodecError, match="shorter than the 32-byte"):
        FrameReassembler().feed(struct.pack("<HI", 0, 31))


def test_reassembler_rejects_nonzero_reserved_field() -> None:
    with pytest.raises(AdsCodecError, match="reserved"):
        FrameReassembler().feed(struct.pack("<HI", 0x1000, 32))


@settings(max_examples=300)
@given(st.lists(st.binary(max_size=80), max_size=6))
def test_reassembler_only_raises_codec_errors_on_random_bytes(
    chunks: list[bytes],
) -> None:
    reassembler = FrameReassembler(max_frame_size=4096)
    try:
        for chunk in chunks:
            reassembler.feed(chunk)
    except AdsCodecError:
        pass


@given(st.binary(max_size=80))
def test_decode_packet_only_raises_codec_errors(raw: bytes) -> None:
    with contextlib.suppress(AdsCodecError):
        decode_packet(raw)


def test_unknown_command_id_survives_decoding() -> None:
    packet = AmsPacket(TARGET, SOURCE, command=0x55)
    decoded = decode_packet(encode_packet(packet))
    assert decoded.command == 0x55
    assert not isinstance(decoded.command, AmsCommand)
