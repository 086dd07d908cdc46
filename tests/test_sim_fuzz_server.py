"""Hypothesis against the running server over real sockets: it never dies.

After any input on one connection, that connection got only well-formed
frames (and maybe a close), and a fresh connection is served as before.
"""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fastcs_ethercat.ads.commands import ReadStateResponse, WriteRequest, WriteResponse
from fastcs_ethercat.ads.constants import AmsCommand, IndexGroup
from fastcs_ethercat.ads.frames import AmsPacket, FrameReassembler, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress
from fastcs_ethercat.sim.runner import SimulatorConfig
from fastcs_ethercat.sim.server import MAX_REQUEST_SIZE
from tests.sim_support import DEVICE_PORT, IO_SERVER_PORT, StandInTarget, request
from tests.sim_thread import SimulatorThread

TARGET = StandInTarget()
IO_SERVER = AmsAddress(TARGET.system_net_id, IO_SERVER_PORT)
DEVICE = AmsAddress(TARGET.system_net_id, DEVICE_PORT)


@pytest.fixture(scope="module")
def sim() -> Iterator[SimulatorThread]:
    with SimulatorThread(TARGET, SimulatorConfig(port=0, udp_port=None)) as sim:
        yield sim


def exchange(port: int, data: bytes, timeout: float = 5) -> tuple[bytes, bool]:
    """Send `data` and half-close; read until the server closes too (or falls
    silent); return (bytes read, closed by the server)."""
    with socket.create_connection(("127.0.0.1", port), timeout=5) as connection:
        try:
            connection.sendall(data)
            connection.shutdown(socket.SHUT_WR)
        except ConnectionError:
            return b"", True
        connection.settimeout(timeout)
        received = bytearray()
        while True:
            try:
                chunk = connection.recv(65536)
            except TimeoutError:
                return bytes(received), False
            except ConnectionError:
                return bytes(received), True
            if not chunk:
                return bytes(received), True
            received += chunk


def frames(data: bytes) -> list[AmsPacket]:
    reassembler = FrameReassembler()
    packets = reassembler.feed(data)
    assert reassembler.buffered == 0
    return packets


def assert_still_serving(port: int) -> None:
    data, _ = exchange(port, encode_packet(request(IO_SERVER, AmsCommand.READ_STATE)))
    (answer,) = frames(data)
    assert ReadStateResponse.decode(answer.payload).ads_state == 5


garbage = st.one_of(
    st.binary(min_size=1, max_size=300),
    st.builds(
        lambda length, body: struct.pack("<HI", 0, length) + body,
        st.integers(0, 0xFFFF_FFFF),
        st.binary(max_size=100),
    ),
    st.builds(
        lambda command, payload, flags: (
            encode_packet(
                AmsPacket(
                    IO_SERVER, DEVICE, command, state_flags=flags, payload=payload
                )
            )
            + b"\x00"
        ),
        st.integers(0, 0xFFFF),
        st.binary(max_size=60),
        st.integers(0, 0xFFFF),
    ),
)


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(garbage)
def test_garbage_gets_frames_or_a_close_and_the_server_lives(
    sim: SimulatorThread, data: bytes
) -> None:
    port = sim.endpoints.tcp_port
    received, _ = exchange(port, data)
    frames(received)
    assert_still_serving(port)


def test_oversized_request_closes_the_connection(sim: SimulatorThread) -> None:
    port = sim.endpoints.tcp_port
    header = struct.pack("<HI", 0, MAX_REQUEST_SIZE + 1)
    received, closed = exchange(port, header + bytes(1024))
    assert (received, closed) == (b"", True)
    assert_still_serving(port)


def test_a_large_valid_request_is_served(sim: SimulatorThread) -> None:
    write = WriteRequest(IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES, 0, bytes(1_000_000))
    data, _ = exchange(
        sim.endpoints.tcp_port,
        encode_packet(request(DEVICE, AmsCommand.WRITE, write.encode())),
    )
    (answer,) = frames(data)
    assert WriteResponse.decode(answer.payload).result == 0x705  # beyond the image


def test_garbage_and_good_clients_at_once(sim: SimulatorThread) -> None:
    port = sim.endpoints.tcp_port
    errors: list[BaseException] = []

    def good(index: int) -> None:
        try:
            batch = b"".join(
                encode_packet(
                    request(IO_SERVER, AmsCommand.READ_STATE, invoke_id=index * 100 + i)
                )
                for i in range(20)
            )
            data, _ = exchange(port, batch)
            got = [p.invoke_id for p in frames(data)]
            assert got == [index * 100 + i for i in range(20)]
        except BaseException as error:
            errors.append(error)

    def bad(index: int) -> None:
        try:
            exchange(port, bytes([index]) * 4096)
        except BaseException as error:
            errors.append(error)

    threads = [threading.Thread(target=good, args=(i,)) for i in range(6)]
    threads += [threading.Thread(target=bad, args=(i,)) for i in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    assert errors == []
    assert_still_serving(port)
