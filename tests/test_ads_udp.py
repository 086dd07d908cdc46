"""UDP discovery and add-route packets against pyads 3.6's own code."""

from __future__ import annotations

import contextlib
import struct
from typing import Any

import pyads.pyads_ex as pyads_ex
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fastcs_ethercat.ads.constants import AdsReturnCode, AmsPort
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.udp import (
    UDP_RESPONSE_FLAG,
    UdpPacket,
    UdpService,
    UdpTag,
    UdpTagValue,
    add_route_reply,
    add_route_request,
    discover_reply,
    discover_request,
)

TARGET = AmsNetId.parse("5.12.34.56.1.1")
CLIENT = AmsNetId.parse("10.0.0.5.1.1")


class FakeUdp:
    """Stands in for pyads' send_raw_udp_message: keeps what pyads sent and
    answers with our encoded reply."""

    def __init__(self, reply: bytes) -> None:
        self.reply = reply
        self.sent: list[bytes] = []

    def __call__(self, ip: str, message: bytes, expected: int) -> tuple[bytes, Any]:
        self.sent.append(message)
        return self.reply[:expected], (ip, 48899)


def test_discover_request_bytes_match_pyads(monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeUdp(discover_reply(TARGET, "sim-host").encode())
    monkeypatch.setattr(pyads_ex, "send_raw_udp_message", fake)
    assert pyads_ex.adsGetNetIdForPLC("127.0.0.1") == str(TARGET)
    (sent,) = fake.sent
    expected = discover_request(AmsNetId.parse("1.1.1.1.1.1")).encode()
    assert sent == expected
    assert sent.hex() == "036614710000000001000000010101010101102700000000"
    request = UdpPacket.decode(sent)
    assert request.base_service == UdpService.DISCOVER and not request.is_reply


def test_discover_reply_layout() -> None:
    raw = discover_reply(TARGET, "sim", (3, 1, 4024)).encode()
    assert raw[:4] == bytes.fromhex("03661471")
    assert raw[11] == 0x80  # reply bit in the service's top byte
    assert raw[12:18] == TARGET.to_bytes()
    assert struct.unpack_from("<H", raw, 18)[0] == AmsPort.SYSTEM_SERVICE
    reply = UdpPacket.decode(raw)
    host = reply.tag(UdpTag.HOST)
    assert host is not None and host.as_text() == "sim"
    version = reply.tag(UdpTag.TWINCAT_VERSION)
    assert version is not None and struct.unpack("<BBH", version.data) == (3, 1, 4024)


def test_add_route_request_matches_pyads(monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeUdp(add_route_reply(TARGET).encode())
    monkeypatch.setattr(pyads_ex, "send_raw_udp_message", fake)
    accepted = pyads_ex.adsAddRouteToPLC(
        str(CLIENT),
        "client-host",
        "127.0.0.1",
        "Administrator",
        "1",
        route_name="route-a",
    )
    assert accepted is True
    (sent,) = fake.sent
    assert (
        sent
        == add_route_request(
            CLIENT, "route-a", CLIENT, "Administrator", "1", "client-host"
        ).encode()
    )
    request = UdpPacket.decode(sent)
    assert [t.tag for t in request.tags] == [
        UdpTag.ROUTE_NAME,
        UdpTag.NETID,
        UdpTag.USER_NAME,
        UdpTag.PASSWORD,
        UdpTag.HOST,
    ]
    netid = request.tag(UdpTag.NETID)
    assert netid is not None and AmsNetId.from_bytes(netid.data) == CLIENT


def test_add_route_reply_is_the_32_bytes_pyads_accepts() -> None:
    raw = add_route_reply(TARGET).encode()
    assert len(raw) == 32
    assert (
        struct.unpack_from("<I", raw, 8)[0] == UdpService.ADD_ROUTE | UDP_RESPONSE_FLAG
    )
    assert raw[24:26] == b"\x01\x00"  # STATUS tag
    assert raw[26:29] == b"\x04\x00\x00"  # what pyads checks
    status = UdpPacket.decode(raw).tag(UdpTag.STATUS)
    assert status is not None and status.as_u32() == 0


def test_pyads_rejects_a_failed_add_route_reply(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    reply = add_route_reply(TARGET, AdsReturnCode.DEVICE_INVALID_ACCESS).encode()
    monkeypatch.setattr(pyads_ex, "send_raw_udp_message", FakeUdp(reply))
    with pytest.raises(RuntimeError, match="Unexpected response"):
        pyads_ex.adsAddRouteToPLC(str(CLIENT), "h", "127.0.0.1", "u", "p")


@pytest.mark.parametrize(
    "raw",
    [
        b"\x00" * 24,  # wrong magic
        discover_request(TARGET).encode()[:23],  # short head
        discover_request(TARGET).encode() + b"x",  # trailing bytes
        discover_request(TARGET).encode()[:20] + struct.pack("<I", 1),  # missing tag
    ],
)
def test_malformed_packets(raw: bytes) -> None:
    with pytest.raises(AdsCodecError):
        UdpPacket.decode(raw)


texts = st.text(
    alphabet=st.characters(codec="cp1252", exclude_characters="\0"), max_size=20
)
packets = st.builds(
    UdpPacket,
    service=st.integers(0, 0xFFFF_FFFF),
    netid=st.tuples(*[st.integers(0, 255)] * 6).map(AmsNetId),
    tags=st.lists(
        st.builds(UdpTagValue, st.integers(0, 0xFFFF), st.binary(max_size=20)),
        max_size=5,
    ).map(tuple),
    port=st.integers(0, 0xFFFF),
    invoke_id=st.integers(0, 0xFFFF_FFFF),
)


@given(packets)
def test_round_trip(packet: UdpPacket) -> None:
    assert UdpPacket.decode(packet.encode()) == packet


@given(st.binary(max_size=80))
def test_decoder_only_raises_codec_errors(raw: bytes) -> None:
    with contextlib.suppress(AdsCodecError):
        UdpPacket.decode(raw)
