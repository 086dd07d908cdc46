"""The session's loopback CA repeater: what clients expect of a repeater, and
that with it no client spawns a caRepeater, even with one on PATH."""

from __future__ import annotations

import os
import socket
import subprocess
from collections.abc import Iterator

import pytest

from tests.ca_repeater import (
    HEADER,
    REPEATER_CONFIRM,
    REPEATER_REGISTER,
    RSRV_IS_UP,
    LoopbackRepeater,
)
from tests.ioc_support import BIN
from tests.processes import SESSION_VARIABLE, command_line, processes_with

LOOPBACK_ADDRESS = 0x7F000001


@pytest.fixture
def repeater() -> Iterator[LoopbackRepeater]:
    running = LoopbackRepeater().start()
    yield running
    running.close()


@pytest.fixture
def client() -> Iterator[socket.socket]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(5)
        yield sock


def test_a_registration_is_confirmed_with_the_client_address(
    repeater: LoopbackRepeater, client: socket.socket
) -> None:
    client.sendto(
        HEADER.pack(REPEATER_REGISTER, 0, 0, 0, 0, 0), ("127.0.0.1", repeater.port)
    )
    answer, sender = client.recvfrom(1024)

    assert sender == ("127.0.0.1", repeater.port)
    assert HEADER.unpack(answer) == (REPEATER_CONFIRM, 0, 0, 0, 0, LOOPBACK_ADDRESS)
    assert client.getsockname() in repeater.clients


def test_a_beacon_reaches_every_registered_client_with_its_server_address(
    repeater: LoopbackRepeater, client: socket.socket
) -> None:
    client.sendto(b"", ("127.0.0.1", repeater.port))  # an old client registers
    client.recvfrom(1024)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as server:
        server.sendto(
            HEADER.pack(RSRV_IS_UP, 0, 13, 5064, 7, 0), ("127.0.0.1", repeater.port)
        )
        beacon = client.recvfrom(1024)[0]

    assert HEADER.unpack(beacon) == (RSRV_IS_UP, 0, 13, 5064, 7, LOOPBACK_ADDRESS)


@pytest.mark.e2e
def test_caget_spawns_no_carepeater_even_with_one_on_path() -> None:
    assert (BIN / "caRepeater").exists()
    env = dict(os.environ, PATH=f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}")
    done = subprocess.run(
        [str(BIN / "caget"), "-w", "0.5", "NO:SUCH:PV"],
        env=env,
        capture_output=True,
        text=True,
        timeout=30,  # a spawned caRepeater keeps the pipes open until this
    )
    ours = processes_with(SESSION_VARIABLE, os.environ[SESSION_VARIABLE])

    assert "NO:SUCH:PV" in done.stdout + done.stderr
    assert not [pid for pid in ours if "caRepeater" in command_line(pid)]
