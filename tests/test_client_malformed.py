"""No byte sequence from the target breaks the client: over a thousand
malformed frames of every kind, then the target turns good again."""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import AsyncIterator

import pytest

from fastcs_ethercat.ads.client import AdsClient, AdsError
from fastcs_ethercat.ads.constants import AdsState, IndexGroup
from fastcs_ethercat.ads.sums import SumReadItem
from fastcs_ethercat.sim.runner import Simulator, SimulatorConfig
from tests.malformed_ads import KINDS, HostileProxy
from tests.sim_support import DEVICE_PORT, StandInTarget

INPUTS = IndexGroup.IO_IMAGE_RW_INPUT_BYTES


@pytest.fixture
async def proxy() -> AsyncIterator[tuple[HostileProxy, Simulator]]:
    simulator = Simulator(StandInTarget(), SimulatorConfig(port=0, udp_port=None))
    await simulator.start()
    hostile = HostileProxy(("127.0.0.1", simulator.endpoints().tcp_port), burst=20)
    await hostile.start()
    yield hostile, simulator
    await hostile.stop()
    await simulator.stop()


async def test_a_thousand_malformed_frames_then_good_again(
    proxy: tuple[HostileProxy, Simulator], caplog: pytest.LogCaptureFixture
) -> None:
    hostile, simulator = proxy
    caplog.set_level(logging.DEBUG, logger="fastcs_ethercat")
    target = simulator.target.system_net_id
    client = AdsClient(
        "127.0.0.1", target, DEVICE_PORT, tcp_port=hostile.port, timeout_ms=300
    )
    async with client:
        assert (await client.read_state()).ads_state is AdsState.RUN
        hostile.bad = True
        started = time.monotonic()
        failures: list[BaseException] = []
        requests = [
            client.read_state,
            lambda: client.read(INPUTS, 0, 16),
            lambda: client.sum_read([SumReadItem(INPUTS, 0, 2)] * 3),
        ]
        n = 0
        while hostile.malformed_sent < 1200:
            try:
                await requests[n % len(requests)]()
            except AdsError as error:
                failures.append(error)
            n += 1
        bad_seconds = time.monotonic() - started
        hostile.bad = False
        # The tail of the last burst may still spoil the next request or two
        # (a frame cut short swallows the next answer): then it is good.
        state = None
        for _ in range(3):
            try:
                state = (await client.read_state()).ads_state
                break
            except AdsError as error:
                failures.append(error)

        assert state is AdsState.RUN
        assert await client.read(INPUTS, 100, 2) == bytes(2)

    stats = client.connection.stats
    assert set(hostile.sent) == {kind.__name__ for kind in KINDS}
    assert len(failures) >= n, "a malformed answer was taken for a good one"
    assert sum(stats.malformed.values()) >= 500, dict(stats.malformed)
    assert stats.connects >= 20  # every broken stream was dropped and reopened
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert 1 <= len(warnings) <= bad_seconds + 2, (bad_seconds, len(warnings))


async def test_notifications_survive_garbage_around_them(
    proxy: tuple[HostileProxy, Simulator],
) -> None:
    """Stray notifications for unknown handles, between good frames, reach
    nobody and stop nothing."""
    hostile, simulator = proxy
    target = simulator.target.system_net_id
    samples: list[bytes] = []
    async with AdsClient(
        "127.0.0.1", target, DEVICE_PORT, tcp_port=hostile.port, timeout_ms=1000
    ) as client:
        await client.add_notification(
            INPUTS, 0, 2, lambda n: samples.append(n.data), cycle_time_ms=10
        )
        await asyncio.sleep(0.3)

    assert len(samples) >= 2
