"""UDP discovery and add-route, checked by pyads' own functions.

pyads always sends to UDP port 48899 (`pyads.pyads_ex.PORT_REMOTE_UDP`); the
tests point that constant at the simulator's free port so parallel runs
cannot collide. The bytes pyads builds and the checks it applies are its own.
"""

from __future__ import annotations

from collections.abc import Iterator

import pyads
import pyads.pyads_ex
import pytest

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.udp import (
    UDP_RESPONSE_FLAG,
    UdpPacket,
    UdpService,
    UdpTag,
    add_route_request,
    discover_request,
)
from fastcs_ethercat.sim.runner import SimulatorConfig
from fastcs_ethercat.sim.udp import UdpResponder
from tests.sim_support import StandInTarget
from tests.sim_thread import SimulatorThread

NET_ID = AmsNetId.parse("10.20.30.40.1.1")
CLIENT = AmsNetId.parse("127.0.0.1.1.20")


@pytest.fixture(scope="module")
def sim() -> Iterator[SimulatorThread]:
    with SimulatorThread(StandInTarget(), SimulatorConfig(port=0, udp_port=0)) as sim:
        yield sim


@pytest.fixture
def pyads_to_sim(sim: SimulatorThread, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pyads.pyads_ex, "PORT_REMOTE_UDP", sim.endpoints.udp_port)


def test_pyads_discovers_the_net_id(pyads_to_sim: None) -> None:
    assert pyads.pyads_ex.adsGetNetIdForPLC("127.0.0.1") == str(NET_ID)


def test_pyads_adds_a_route(sim: SimulatorThread, pyads_to_sim: None) -> None:
    added = pyads.add_route_to_plc(
        str(CLIENT), "127.0.0.1", "127.0.0.1", "Administrator", "1", route_name="test"
    )
    assert added is True
    assert sim.simulator.udp is not None
    route = sim.simulator.udp.routes[-1]
    assert (route.name, route.netid, route.host, route.user) == (
        "test",
        CLIENT,
        "127.0.0.1",
        "Administrator",
    )


def test_wrong_password_is_refused_as_twincat_refuses_it() -> None:
    responder = UdpResponder(NET_ID, credentials=("Administrator", "1"))
    request = add_route_request(CLIENT, "r", CLIENT, "Administrator", "2", "h")
    reply = responder.answer(request.encode())
    assert reply is not None
    status = UdpPacket.decode(reply).tag(UdpTag.STATUS)
    assert status is not None
    assert status.as_u32() == AdsReturnCode.DEVICE_INVALID_ACCESS
    assert reply[26:32] == bytes.fromhex("040004070000")  # as real targets answer
    assert responder.routes == []


def test_discover_reply_carries_host_and_version() -> None:
    responder = UdpResponder(NET_ID, host_name="sim-host", twincat_version=(3, 1, 4026))
    reply = UdpPacket.decode(responder.answer(discover_request(CLIENT).encode()) or b"")
    assert reply.service == UdpService.DISCOVER | UDP_RESPONSE_FLAG
    assert reply.netid == NET_ID
    host = reply.tag(UdpTag.HOST)
    assert host is not None and host.as_text() == "sim-host"
    version = reply.tag(UdpTag.TWINCAT_VERSION)
    assert version is not None and version.data == bytes([3, 1]) + (4026).to_bytes(
        2, "little"
    )


@pytest.mark.parametrize(
    "datagram",
    [
        b"",
        b"\x00" * 24,
        bytes.fromhex("03661471") + b"\x00" * 3,
        UdpPacket(UdpService.DISCOVER | UDP_RESPONSE_FLAG, NET_ID).encode(),
        UdpPacket(99, NET_ID).encode(),
        discover_request(CLIENT).encode() + b"\x01",
    ],
)
def test_anything_else_is_ignored(datagram: bytes) -> None:
    responder = UdpResponder(NET_ID)
    assert responder.answer(datagram) is None
    assert responder.ignored == 1
