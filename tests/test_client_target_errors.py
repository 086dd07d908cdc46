"""Target errors say what they are: refused, unreachable, unknown host,
timeout; never an AMS routing code for a socket error.

A closed port is real (nothing listens on it); the others would need packets
to leave loopback, so the socket layer is made to fail the way the kernel
does (only the connect call is replaced)."""

from __future__ import annotations

import asyncio
import errno
import socket
from collections.abc import Callable
from typing import Any

import pytest

from fastcs_ethercat.ads.client import (
    AdsClient,
    AdsConnectionError,
    AdsConnectionRefusedError,
    AdsConnectTimeoutError,
    AdsHostUnreachableError,
    AdsTimeoutError,
    AdsUnknownHostError,
    unreachable,
)
from fastcs_ethercat.ads.connection import AmsTcpConnection
from fastcs_ethercat.ads.constants import AdsReturnCode

NET_ID = "192.0.2.40.1.1"


def closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def failing_connect(
    monkeypatch: pytest.MonkeyPatch, failure: Callable[[], Any]
) -> None:
    async def connect(*_: object, **__: object) -> Any:
        return await failure()

    monkeypatch.setattr(
        asyncio.get_running_loop(), "create_connection", connect, raising=False
    )


async def test_a_closed_port_is_connection_refused() -> None:
    port = closed_port()
    client = AdsClient("127.0.0.1", NET_ID, 851, tcp_port=port)

    with pytest.raises(AdsConnectionRefusedError) as refused:
        await client.open()
    await client.close()

    assert str(refused.value) == f"cannot reach 127.0.0.1:{port}: connection refused"
    assert refused.value.code == AdsReturnCode.SOCKET_CONNECTION_REFUSED
    assert refused.value.code != AdsReturnCode.TARGET_PORT_NOT_FOUND
    assert unreachable(refused.value.code)


async def test_no_route_to_the_host(monkeypatch: pytest.MonkeyPatch) -> None:
    async def no_route() -> None:
        raise OSError(errno.EHOSTUNREACH, "No route to host")

    failing_connect(monkeypatch, no_route)
    client = AdsClient("10.0.0.5", NET_ID, 851)

    with pytest.raises(AdsHostUnreachableError) as failed:
        await client.read_state()

    assert str(failed.value) == "cannot reach 10.0.0.5:48898: no route to host"
    assert failed.value.code == AdsReturnCode.SOCKET_HOST_UNREACHABLE


async def test_an_unknown_host_name(monkeypatch: pytest.MonkeyPatch) -> None:
    async def no_such_name() -> None:
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    failing_connect(monkeypatch, no_such_name)
    client = AdsClient("plc-that-is-not.example", NET_ID, 851)

    with pytest.raises(AdsUnknownHostError) as failed:
        await client.read_state()

    assert "unknown host name 'plc-that-is-not.example'" in str(failed.value)
    assert failed.value.code == AdsReturnCode.SOCKET_HOST_NOT_FOUND


async def test_a_connect_that_hangs_times_out(monkeypatch: pytest.MonkeyPatch) -> None:
    async def hang() -> None:
        await asyncio.sleep(60)

    failing_connect(monkeypatch, hang)
    connection = AmsTcpConnection("10.0.0.5", connect_timeout_s=0.2)
    client = AdsClient("10.0.0.5", NET_ID, 851, connection=connection)

    with pytest.raises(AdsConnectTimeoutError) as failed:
        await client.read_state()

    assert isinstance(failed.value, AdsTimeoutError)
    assert isinstance(failed.value, AdsConnectionError)
    assert str(failed.value) == "cannot reach 10.0.0.5:48898: no answer in 0.2 s"
    assert failed.value.code == AdsReturnCode.SOCKET_CONNECTION_TIMEOUT


async def test_one_attempt_serves_every_request_waiting_for_it() -> None:
    port = closed_port()
    connection = AmsTcpConnection("127.0.0.1", port)
    clients = [
        AdsClient("127.0.0.1", NET_ID, 851 + n, connection=connection) for n in range(5)
    ]

    results = await asyncio.gather(
        *(client.read_state() for client in clients), return_exceptions=True
    )

    assert all(isinstance(r, AdsConnectionRefusedError) for r in results)
    assert connection.stats.connects == 0
