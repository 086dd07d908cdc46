"""AMS NetIds and addresses: text and wire forms."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pyads.structs import AmsAddr, SAmsAddr

from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId

netids = st.tuples(*[st.integers(0, 255)] * 6).map(AmsNetId)


def test_parse_and_format() -> None:
    netid = AmsNetId.parse("5.12.34.56.1.1")
    assert netid.to_bytes() == bytes([5, 12, 34, 56, 1, 1])
    assert str(netid) == "5.12.34.56.1.1"
    assert AmsNetId.from_ip("127.0.0.1") == AmsNetId.parse("127.0.0.1.1.1")
    assert netid.with_octet(4, 2) == AmsNetId.parse("5.12.34.56.2.1")


def test_address_wire_form_matches_pyads_struct() -> None:
    """pyads' ctypes SAmsAddr (packed NetId + u16 port) has our 8 bytes."""
    address = AmsAddress.parse("5.12.34.56.1.1:27905")
    pyads_address = AmsAddr("5.12.34.56.1.1", 27905).amsAddrStruct()
    assert bytes(pyads_address) == address.to_bytes()
    back = SAmsAddr.from_buffer_copy(address.to_bytes())
    assert ".".join(map(str, back.netId.b)) == "5.12.34.56.1.1"
    assert back.port == 27905
    assert str(address) == "5.12.34.56.1.1:27905"


@pytest.mark.parametrize(
    "text",
    [
        "",
        "1.2.3.4.5",
        "1.2.3.4.5.6.7",
        "1.2.3.4.5.256",
        "a.b.c.d.e.f",
        "-1.2.3.4.5.6",
        "1.2.3.4.5.\u0661",
    ],
)
def test_bad_netid_text(text: str) -> None:
    with pytest.raises(AdsCodecError):
        AmsNetId.parse(text)


def test_bad_address() -> None:
    with pytest.raises(AdsCodecError):
        AmsAddress.parse("1.2.3.4.5.6")
    with pytest.raises(AdsCodecError):
        AmsAddress(AmsNetId.parse("1.2.3.4.5.6"), 70000)
    with pytest.raises(AdsCodecError):
        AmsAddress.from_bytes(b"\x00" * 7)


@given(netids, st.integers(0, 0xFFFF))
def test_round_trips(netid: AmsNetId, port: int) -> None:
    assert AmsNetId.parse(str(netid)) == netid
    assert AmsNetId.from_bytes(netid.to_bytes()) == netid
    address = AmsAddress(netid, port)
    assert AmsAddress.from_bytes(address.to_bytes()) == address
    assert AmsAddress.parse(str(address)) == address
