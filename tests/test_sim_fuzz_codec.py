"""Hypothesis against the codec as the simulator uses it, in process (fast).

Whatever arrives, a connection either answers with well-formed frames or
closes; nothing escapes `data_received`. The UDP responder, the notification
registry and the control routes never raise anything but their own errors.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import struct
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    decode_request,
    decode_response,
)
from fastcs_ethercat.ads.constants import AmsCommand
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import (
    AmsPacket,
    FrameReassembler,
    encode_packet,
)
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.udp import UdpPacket
from fastcs_ethercat.sim.control import ControlError, ControlRoutes, SimControl
from fastcs_ethercat.sim.faults import FaultError, parse_fault
from fastcs_ethercat.sim.notifications import HandleAllocator, NotificationRegistry
from fastcs_ethercat.sim.server import AmsConnection, AmsServer
from fastcs_ethercat.sim.udp import UdpResponder
from fastcs_ethercat.twincat.target import SimTarget
from tests.ads_codec import decode_packet
from tests.conftest import REPO_ROOT
from tests.sim_support import DEVICE_PORT, IO_SERVER_PORT, StandInTarget

TARGET = StandInTarget()
FUZZ = settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


class RecordingTransport(asyncio.Transport):
    """Collects what a connection writes; remembers whether it closed."""

    def __init__(self) -> None:
        super().__init__()
        self.written = bytearray()
        self.closed = False

    def write(self, data: bytes | bytearray | memoryview) -> None:
        assert not self.closed, "wrote after close"
        self.written += data

    def close(self) -> None:
        self.closed = True

    def abort(self) -> None:
        self.closed = True

    def is_closing(self) -> bool:
        return self.closed

    def get_write_buffer_size(self) -> int:
        return 0

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        return ("127.0.0.1", 1) if name == "peername" else default


def feed(chunks: list[bytes]) -> RecordingTransport:
    connection = AmsConnection(AmsServer(TARGET))
    transport = RecordingTransport()
    connection.connection_made(transport)
    for chunk in chunks:
        if transport.closed:
            break
        connection.data_received(chunk)
    connection.connection_lost(None)
    return transport


def answers(written: bytes) -> list[AmsPacket]:
    reassembler = FrameReassembler()
    packets = reassembler.feed(written)
    assert reassembler.buffered == 0, "a partial frame was written"
    return packets


net_ids = st.sampled_from(
    [TARGET.system_net_id, TARGET.device_net_id, AmsNetId.parse("1.2.3.4.5.6")]
)
ports = st.sampled_from([IO_SERVER_PORT, DEVICE_PORT, 851, 0xFFFF])
commands = st.one_of(st.sampled_from(list(AmsCommand)), st.integers(0, 0xFFFF))
requests = st.builds(
    AmsPacket,
    target=st.builds(AmsAddress, net_ids, ports),
    source=st.builds(AmsAddress, st.just(AmsNetId.parse("10.0.0.9.1.1")), ports),
    command=commands,
    state_flags=st.sampled_from([0x0004, 0x0004, 0x0005, 0x0000, 0xFFFF]),
    invoke_id=st.integers(0, 0xFFFF_FFFF),
    payload=st.binary(max_size=64),
)


@FUZZ
@given(st.lists(st.binary(min_size=1, max_size=100), max_size=20))
def test_random_bytes_get_frames_or_a_close(chunks: list[bytes]) -> None:
    transport = feed(chunks)
    answers(bytes(transport.written))


@FUZZ
@given(st.lists(requests, min_size=1, max_size=10), st.data())
def test_every_request_is_answered_once_in_order_however_split(
    packets: list[AmsPacket], data: st.DataObject
) -> None:
    stream = b"".join(encode_packet(p) for p in packets)
    cuts = sorted(data.draw(st.sets(st.integers(1, max(1, len(stream) - 1)))))
    chunks = [
        stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)
    ]
    transport = feed(chunks)
    assert not transport.closed
    expected = [
        p.invoke_id
        for p in packets
        if not p.state_flags & 0x0001 and p.command != AmsCommand.DEVICE_NOTIFICATION
    ]
    got = answers(bytes(transport.written))
    assert [a.invoke_id for a in got] == expected
    for answer in got:
        assert answer.is_response
        assert answer.source.netid in (*TARGET.net_ids, AmsNetId.parse("1.2.3.4.5.6"))


@FUZZ
@given(st.integers(0, 0xFFFF), st.binary(max_size=80))
def test_request_decoding_raises_only_codec_errors(
    command: int, payload: bytes
) -> None:
    with contextlib.suppress(AdsCodecError):
        decode_request(command, payload)


@FUZZ
@given(st.binary(max_size=200))
def test_udp_responder_answers_or_ignores(datagram: bytes) -> None:
    reply = UdpResponder(TARGET.system_net_id).answer(datagram)
    if reply is not None:
        assert UdpPacket.decode(reply).is_reply


@FUZZ
@given(
    st.builds(
        AddDeviceNotificationRequest,
        st.integers(0, 0xFFFF_FFFF),
        st.integers(0, 0xFFFF_FFFF),
        st.integers(0, 0xFFFF_FFFF),
        st.integers(0, 0xFFFF_FFFF),
        st.integers(0, 0xFFFF_FFFF),
        st.integers(0, 0xFFFF_FFFF),
    ),
    st.integers(0, 10**12),
)
def test_notification_registry_survives_any_registration(
    request: AddDeviceNotificationRequest, now_ns: int
) -> None:
    registry = NotificationRegistry(TARGET.read, HandleAllocator())
    packet = AmsPacket(
        AmsAddress(TARGET.system_net_id, DEVICE_PORT),
        AmsAddress(AmsNetId.parse("10.0.0.9.1.1"), 30000),
        AmsCommand.ADD_DEVICE_NOTIFICATION,
    )
    result, handle = registry.add(packet, request, now_ns)
    assert (result == 0) == (handle != 0)
    frames, _ = registry.tick(now_ns + 1, 0)
    for frame in frames:
        assert decode_packet(frame).command == AmsCommand.DEVICE_NOTIFICATION


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10),
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=8,
)
fault_bodies = st.one_of(
    json_values,
    st.fixed_dictionaries(
        {
            "kind": st.sampled_from(
                ["drop", "refuse", "stall", "error", "slave_state", "link_lost", "x"]
            )
        },
        optional={
            "seconds": json_values,
            "code": json_values,
            "group": json_values,
            "state": json_values,
            "address": json_values,
            "lost": json_values,
        },
    ),
)


@FUZZ
@given(fault_bodies)
def test_fault_parsing_raises_only_fault_errors(body: Any) -> None:
    with contextlib.suppress(FaultError):
        parse_fault(body)


class _InertControl(SimControl):
    """A SimControl that accepts every operation and does nothing."""

    def __init__(self) -> None:
        pass

    def counters(self) -> dict[str, Any]:
        return {}

    def reset_counters(self) -> dict[str, Any]:
        return {}

    def get_symbol(self, name: str) -> Any:
        raise KeyError(name)

    def set_symbol(self, name: str, value: Any) -> Any:
        raise KeyError(name)

    def add_fault(self, kind: Any, **params: Any) -> Any:
        return kind

    def clear_faults(self) -> None:
        pass

    def faults(self) -> list[dict[str, Any]]:
        return []

    def status(self) -> dict[str, Any]:
        return {}


@FUZZ
@given(
    st.sampled_from(["GET", "PUT", "POST", "DELETE", "PATCH", "X"]),
    st.sampled_from(["/faults", "/symbols/", "/symbols/a%20b", "/x", "/counters", "/"]),
    st.one_of(
        st.binary(max_size=40), json_values.map(lambda v: json.dumps(v).encode())
    ),
)
def test_control_routes_answer_or_raise_control_errors(
    method: str, path: str, body: bytes
) -> None:
    routes = ControlRoutes(_InertControl())
    with contextlib.suppress(ControlError):
        routes.handle(method, path, body)


# -- the real model behind the server ------------------------------------------------

DEMO = SimTarget.from_chain(
    REPO_ROOT / "ioc" / "demo-chain.yaml", REPO_ROOT / "terminals"
)
DEMO_PORTS = [300, 10000, 27905, 0xFFFF, 1001, 1005, 1008, 1014, 999]
GROUPS = [
    *range(0xF003, 0xF010),
    0xF020,
    0xF021,
    0xF025,
    0xF030,
    0xF031,
    0xF035,
    *range(0xF080, 0xF087),
    0xF302,
    0x03,
    0x06,
    0x07,
    0x09,
    0x0C,
    0x11,
    0x12,
    0x5000,
    0x5001,
    0x4020,
]
model_requests = st.builds(
    lambda net_id, port, command, group, offset, length, data, invoke_id: AmsPacket(
        AmsAddress(net_id, port),
        AmsAddress(AmsNetId.parse("10.0.0.9.1.1"), 30000),
        command,
        invoke_id=invoke_id,
        payload={
            AmsCommand.READ: struct.pack("<III", group, offset, length),
            AmsCommand.WRITE: struct.pack("<III", group, offset, len(data)) + data,
            AmsCommand.READ_WRITE: struct.pack(
                "<IIII", group, offset, length, len(data)
            )
            + data,
        }.get(command, data),
    ),
    st.sampled_from(sorted(DEMO.net_ids)),
    st.sampled_from(DEMO_PORTS),
    st.sampled_from(list(AmsCommand)),
    st.sampled_from(GROUPS),
    st.one_of(st.integers(0, 64), st.integers(0, 0xFFFF_FFFF)),
    st.one_of(st.integers(0, 64), st.integers(0, 0xFFFF_FFFF)),
    st.binary(max_size=48),
    st.integers(1, 0xFFFF),
)


class _Errors(logging.Handler):
    """Collects error records (the server logs a model that raised)."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@FUZZ
@given(st.lists(model_requests, min_size=1, max_size=8))
def test_the_real_model_answers_every_request_without_failing(
    packets: list[AmsPacket],
) -> None:
    connection = AmsConnection(AmsServer(DEMO))
    transport = RecordingTransport()
    connection.connection_made(transport)
    errors = _Errors()
    logger = logging.getLogger("fastcs_ethercat.sim.server")
    logger.addHandler(errors)
    try:
        connection.data_received(b"".join(encode_packet(p) for p in packets))
    finally:
        logger.removeHandler(errors)
    assert errors.messages == []
    expected = [
        p.invoke_id for p in packets if p.command != AmsCommand.DEVICE_NOTIFICATION
    ]
    got = answers(bytes(transport.written))
    assert [a.invoke_id for a in got] == expected
    for answer in got:
        if answer.error_code == 0:
            decode_response(int(answer.command), answer.payload)
    connection.connection_lost(None)
