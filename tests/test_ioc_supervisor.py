"""The supervisor tells a lost target from a slow one: a probe that times out
while the target's connection still brings frames is slow, up to a limit."""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass, field
from typing import Any

import pytest

from fastcs_ethercat.ads.errors import AdsTimeoutError
from fastcs_ethercat.ioc.supervisor import Backoff, LinkState, Probe, Supervisor

TIMEOUT_S = 0.02


@dataclass
class RecordingLink:
    calls: list[str] = field(default_factory=list)

    async def lost(self, reason: str) -> None:
        self.calls.append(f"lost: {reason}")

    async def stopped(self, ads_state: int) -> None:
        self.calls.append("stopped")

    async def reconnect(self) -> int:
        self.calls.append("reconnect")
        return 7

    async def resync(self, why: str) -> int:
        self.calls.append("resync")
        return 7


def _frames_flowing(probe: Any, link: RecordingLink) -> Supervisor:
    """A supervisor of symbol version 7 whose target keeps sending frames
    (heard now), a probe slow after 0.1 s."""
    return Supervisor(
        probe,
        link,
        7,
        probe_timeout_s=TIMEOUT_S,
        heard_at=time.monotonic,
        slow_limit_s=0.1,
    )


async def hung_probe() -> Probe:
    await asyncio.sleep(10)
    return Probe(5, 7)


def supervisor(link: RecordingLink, heard_at: float | None) -> Supervisor:
    """`heard_at`: None, the target sends nothing; else frames keep coming."""
    return Supervisor(
        hung_probe,
        link,
        7,
        probe_timeout_s=TIMEOUT_S,
        heard_at=lambda: time.monotonic() if heard_at is not None else 0.0,
        slow_limit_s=0.2,
    )


async def test_a_silent_target_is_lost_at_the_first_timeout() -> None:
    link = RecordingLink()
    watch = supervisor(link, heard_at=None)
    await watch.step()
    assert link.calls[:2] == [
        f"lost: no answer from the target in {TIMEOUT_S} s",
        "reconnect",
    ]
    assert watch.stats.losses == 1


async def test_a_target_that_still_sends_is_slow_until_the_limit() -> None:
    link = RecordingLink()
    watch = supervisor(link, heard_at=0.0)
    started = time.monotonic()
    while not link.calls:
        await watch.step()
    waited = time.monotonic() - started
    assert link.calls[0].startswith("lost: no answer")
    assert waited >= 0.2  # the limit, not the first timeout
    assert watch.stats.losses == 1
    assert watch.state is LinkState.CONNECTED  # reconnected


async def test_an_answer_ends_the_slow_spell() -> None:
    answers = [False, True] * 6  # slow, answered, ...: 0.3 s, past the limit

    async def probe() -> Probe:
        if not answers.pop(0):
            await asyncio.sleep(10)
        return Probe(5, 7)

    link = RecordingLink()
    watch = _frames_flowing(probe, link)
    started = time.monotonic()
    while answers:
        await watch.step()
        await asyncio.sleep(0.03)
    assert time.monotonic() - started > 0.2
    assert link.calls == []  # each answer began a fresh spell


async def test_an_online_change_after_a_loss_is_no_reconnect(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A loss ends with a reconnect (counted, its time from the loss); an
    online change later is a resync: counted as one, logged with its own
    time, never "after the loss" of the outage before."""
    versions = [7, 8]
    silent = [True]

    async def probe() -> Probe:
        if silent[0]:
            silent[0] = False
            await asyncio.sleep(10)
        return Probe(5, versions[0])

    link = RecordingLink()
    watch = Supervisor(
        probe, link, 7, probe_timeout_s=TIMEOUT_S, backoff=Backoff(first_s=0.01)
    )
    with caplog.at_level(logging.INFO):
        await watch.step()  # lost, reconnected
        after_loss = watch.stats.last_recovery_s
        versions.pop(0)  # an online change
        await watch.step()
    lines = [r.getMessage() for r in caplog.records]

    assert watch.stats.reconnects == 1 and watch.stats.resyncs == 1
    assert watch.stats.last_recovery_s == after_loss
    assert sum("after the loss" in line for line in lines) == 1
    assert any("resolved again in" in line for line in lines), lines
    assert watch.state is LinkState.CONNECTED


async def test_the_clients_own_timeout_is_slow_while_frames_come() -> None:
    """A probe that fails with the ADS client's timeout (shorter than the
    probe's) while the target still sends is slow, as a probe timeout is;
    lost once the limit has passed."""

    async def probe() -> Probe:
        raise AdsTimeoutError(0x745, "read state", "target")

    link = RecordingLink()
    watch = _frames_flowing(probe, link)
    await watch.step()
    first = list(link.calls)
    started = time.monotonic()
    while not link.calls:
        await watch.step()
        await asyncio.sleep(0.01)

    assert first == []
    assert time.monotonic() - started >= 0.09
    assert link.calls[0].startswith("lost: AdsTimeoutError")
