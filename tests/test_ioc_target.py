"""Preparing the target from the IOC configuration: route, NetId, user errors.

The simulator's UDP responder plays the target's system service on UDP 48899
(the only port pyads talks to), on a loopback address of its own.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Iterator
from typing import Final

import pytest

from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.ioc.target import prepare_target
from fastcs_ethercat.sim.udp import UdpResponder

TARGET_NET_ID: Final = AmsNetId.parse("192.0.2.33.1.1")
PASSWORD: Final = "correct horse"
PASSWORD_ENV: Final = "FASTCS_ETHERCAT_TEST_TARGET_PASSWORD"


@pytest.fixture(scope="module")
def responder() -> Iterator[tuple[UdpResponder, str]]:
    udp = UdpResponder(TARGET_NET_ID, credentials=("Administrator", PASSWORD))
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()

    async def start() -> str:
        for host in ("127.0.0.1", "127.0.0.5", "127.0.0.6", "127.0.0.7"):
            with contextlib.suppress(OSError):
                await udp.start(host, 48899)
                return host
        raise RuntimeError("UDP 48899 is taken on every loopback address tried")

    host = asyncio.run_coroutine_threadsafe(start(), loop).result(10)
    yield udp, host
    loop.call_soon_threadsafe(udp.close)
    loop.call_soon_threadsafe(loop.stop)
    thread.join(10)
    loop.close()


async def test_discovers_the_net_id_and_adds_the_route(
    responder: tuple[UdpResponder, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    udp, host = responder
    monkeypatch.setenv(PASSWORD_ENV, PASSWORD)
    config = load_ioc_config(
        None,
        {
            "prefix": "X",
            "target": host,
            "route.password_env": PASSWORD_ENV,
            "route.route_name": "ioc-test",
        },
    )

    net_id = await prepare_target(config)

    assert net_id == TARGET_NET_ID
    assert [(r.name, r.user, r.host) for r in udp.routes][-1] == (
        "ioc-test",
        "Administrator",
        "127.0.0.1",
    )


async def test_a_configured_net_id_needs_no_discovery() -> None:
    config = load_ioc_config(
        None, {"prefix": "X", "target": "127.0.0.9", "ams_net_id": "192.0.2.1.1.1"}
    )

    assert await prepare_target(config) == AmsNetId.parse("192.0.2.1.1.1")


async def test_a_refused_route_is_a_user_error_without_the_password(
    responder: tuple[UdpResponder, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, host = responder
    monkeypatch.setenv(PASSWORD_ENV, "not the " + PASSWORD)
    config = load_ioc_config(
        None, {"prefix": "X", "target": host, "route.password_env": PASSWORD_ENV}
    )

    with pytest.raises(UserError, match=r"^route: add route on ") as error:
        await prepare_target(config)

    assert PASSWORD not in str(error.value)


async def test_a_silent_target_is_a_user_error() -> None:
    config = load_ioc_config(None, {"prefix": "X", "target": "127.0.0.9"})

    with pytest.raises(UserError, match=r"^target: NetId discovery on 127.0.0.9"):
        await prepare_target(config)
