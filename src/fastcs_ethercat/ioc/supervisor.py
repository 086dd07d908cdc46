"""Connection supervision: watch the target's ADS state, reconnect with backoff.

Every `period` the supervisor asks the target for its ADS state and symbol
version (`probe`). What it finds goes to a `Link` (the app), which does the
work:

- no answer in `probe_timeout` (or an ADS error): `lost`, then `reconnect`
  with growing pauses until it succeeds (the app closes and reopens its
  clients, discovers again and resumes polling). A probe that times out
  (its own timeout, or the ADS client's when that is shorter) while the
  target's connection still brings frames is slow, not lost (a
  loaded host, ours or the PLC's): lost only once probes have gone
  unanswered for `SLOW_PROBE_LIMIT_S`;
- the runtime not in RUN: `stopped` once; back in RUN: `resync`;
- another symbol version (online change), or a master whose symbol handles
  went invalid (`request_resync`: the only sign of an online change where
  the device port does not answer 0xF008): `resync`.

An IOC that booted without its target (from a chain file) starts
disconnected: it reconnects first. Failed attempts are logged at most once
per `RECONNECT_LOG_INTERVAL_S`.

A beamline IOC runs for months: nothing here ends except by cancellation.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Final, Protocol

from fastcs_ethercat.ads.constants import AdsState
from fastcs_ethercat.ads.errors import AdsTimeoutError
from fastcs_ethercat.ads.ratelimit import RateLimitedLog

logger = logging.getLogger(__name__)

PROBE_PERIOD_S: Final = 0.2
PROBE_TIMEOUT_S: Final = 0.5
"""A loss shows within PROBE_PERIOD_S + PROBE_TIMEOUT_S (0.7 s) plus the time
to mark every PV INVALID: inside the 1 s issue 5 asks for, while a probe may
still take half a second on a loaded host before it counts as lost."""
SLOW_PROBE_LIMIT_S: Final = 3.0
"""How long probes may time out while other answers still come from the target
before it counts as lost (its I/O server hangs while the router answers)."""
RECONNECT_TIMEOUT_S: Final = 30.0
RECONNECT_LOG_INTERVAL_S: Final = 10.0
"""At most one line per this interval about failed reconnects (an outage of
a night would otherwise write one every backoff pause)."""
REQUESTED_RESYNC_EVERY_S: Final = 1.0
"""Resyncs asked for by the masters come at most this often (a target whose
handles keep failing must not make the IOC resolve in a loop)."""


class LinkState(StrEnum):
    """What the root's `ConnectionState` shows."""

    CONNECTED = "CONNECTED"
    DISCONNECTED = "DISCONNECTED"
    STOPPED = "STOPPED"
    RESYNCING = "RESYNCING"


@dataclass(frozen=True)
class Probe:
    """One answer of the target: ADS state and symbol version."""

    ads_state: int
    symbol_version: int


Prober = Callable[[], Awaitable[Probe]]
HeardAt = Callable[[], float]
"""time.monotonic() of the last frame from the target."""


class Link(Protocol):
    """What the supervisor drives (implemented by the app)."""

    async def lost(self, reason: str) -> None: ...
    async def stopped(self, ads_state: int) -> None: ...
    async def reconnect(self) -> int:
        """Reopen, discover, resume; returns the symbol version now served."""
        ...

    async def resync(self, why: str) -> int:
        """Re-resolve over open clients and resume; the symbol version."""
        ...


@dataclass
class Backoff:
    """Pauses between reconnect attempts: first, first*factor, ... up to most."""

    first_s: float = 0.2
    factor: float = 2.0
    most_s: float = 2.0

    def pauses(self) -> Callable[[], float]:
        pause = [self.first_s]

        def next_pause() -> float:
            now = pause[0]
            pause[0] = min(now * self.factor, self.most_s)
            return now

        return next_pause


@dataclass
class SupervisorStats:
    """For the root's PVs and the tests."""

    state: LinkState = LinkState.CONNECTED
    probes: int = 0
    losses: int = 0
    reconnects: int = 0
    """Outages ended: reconnects after a loss, RUN again after a stop."""
    resyncs: int = 0
    """Symbols resolved again (online changes, a stop's end included)."""
    last_error: str = ""
    lost_at: float = 0.0
    """time.monotonic() of the start of the outage under way (0: none)."""
    last_recovery_s: float = 0.0


class Supervisor:
    """Runs the probe loop against one target."""

    def __init__(
        self,
        probe: Prober,
        link: Link,
        symbol_version: int,
        *,
        period_s: float = PROBE_PERIOD_S,
        probe_timeout_s: float = PROBE_TIMEOUT_S,
        backoff: Backoff | None = None,
        connected: bool = True,
        heard_at: HeardAt = lambda: 0.0,
        slow_limit_s: float = SLOW_PROBE_LIMIT_S,
    ) -> None:
        self.probe = probe
        self.heard_at = heard_at
        self.slow_limit_s = slow_limit_s
        self.link = link
        self.symbol_version = symbol_version
        self.period_s = period_s
        self.probe_timeout_s = probe_timeout_s
        self.backoff = backoff or Backoff()
        self.stats = SupervisorStats()
        self._first_contact = not connected
        if not connected:  # booted without the target: reconnect first
            self.stats.state = LinkState.DISCONNECTED
            self.stats.lost_at = time.monotonic()
        self._wake = asyncio.Event()
        self._rare_log = RateLimitedLog(logger, RECONNECT_LOG_INTERVAL_S)
        self._resync_wanted = ""
        self._last_requested = -REQUESTED_RESYNC_EVERY_S
        self._slow_since: float | None = None

    @property
    def state(self) -> LinkState:
        return self.stats.state

    def poke(self) -> None:
        """Probe now (a poll cycle failed as a whole)."""
        self._wake.set()

    def request_resync(self, why: str) -> None:
        """Resolve every symbol again at the next probe (within
        REQUESTED_RESYNC_EVERY_S of the last such request)."""
        if not self._resync_wanted:
            self._resync_wanted = why
        self._wake.set()

    async def run(self) -> None:
        if self.stats.state is LinkState.DISCONNECTED:
            await self._reconnect()
        while True:
            await self.step()
            self._wake.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._wake.wait(), self.period_s)

    async def step(self) -> None:
        """One probe and whatever it calls for; never raises."""
        try:
            await self._step()
        except asyncio.CancelledError:
            raise
        except Exception as error:  # keep supervising whatever happened
            self.stats.last_error = f"{type(error).__name__}: {error}"
            logger.exception("supervisor step failed")

    async def _step(self) -> None:
        self.stats.probes += 1
        sent = time.monotonic()
        try:
            answer = await asyncio.wait_for(self.probe(), self.probe_timeout_s)
        except (TimeoutError, AdsTimeoutError) as error:
            # the client's own timeout (shorter than the probe's) is no answer
            # in time too: slow, not lost, while the target still sends
            if not self._slow(sent):
                reason = (
                    f"no answer from the target in {self.probe_timeout_s} s"
                    if isinstance(error, TimeoutError)
                    else f"{type(error).__name__}: {error}"
                )
                await self._lose(reason)
            return
        except Exception as error:
            await self._lose(f"{type(error).__name__}: {error}")
            return
        self._slow_since = None
        if answer.ads_state != AdsState.RUN:
            if self.stats.state is not LinkState.STOPPED:
                self.stats.state = LinkState.STOPPED
                self.stats.lost_at = time.monotonic()
                self.stats.last_error = (
                    f"runtime not in RUN (ADS state {answer.ads_state})"
                )
                logger.warning("target: %s", self.stats.last_error)
                await self.link.stopped(answer.ads_state)
            return
        if self.stats.state is LinkState.STOPPED:
            await self._resync("runtime back in RUN")
        elif answer.symbol_version != self.symbol_version:
            await self._resync(
                f"symbol version {self.symbol_version} -> {answer.symbol_version}"
            )
        elif self._resync_wanted:
            now = time.monotonic()
            if now - self._last_requested >= REQUESTED_RESYNC_EVERY_S:
                self._last_requested = now
                await self._resync(self._resync_wanted)

    def _slow(self, sent: float) -> bool:
        """A timed-out probe sent at `sent` is only slow while frames still
        came from the target since, for at most `slow_limit_s`."""
        if self.heard_at() >= sent:
            if self._slow_since is None:
                self._slow_since = sent
            if time.monotonic() - self._slow_since <= self.slow_limit_s:
                self._rare_log.warning(
                    "slow probe",
                    "target slow: no answer to a probe in %s s while other "
                    "frames still come (lost after %s s of this)",
                    self.probe_timeout_s,
                    self.slow_limit_s,
                )
                return True
        self._slow_since = None
        return False

    async def _resync(self, why: str) -> None:
        self._resync_wanted = ""
        logger.warning("target: %s: resolving every symbol again", why)
        outage = self.stats.state is LinkState.STOPPED
        self.stats.state = LinkState.RESYNCING
        started = time.monotonic()
        try:
            self.symbol_version = await self.link.resync(why)
        except Exception as error:
            await self._lose(f"resync failed: {type(error).__name__}: {error}")
            return
        self.stats.resyncs += 1
        if outage:  # back in RUN: the end of an outage, like a reconnect
            self.stats.reconnects += 1
            self._connected()
            return
        self.stats.state = LinkState.CONNECTED
        logger.info(
            "target: every symbol resolved again in %.1f s: polling",
            time.monotonic() - started,
        )

    async def _lose(self, reason: str) -> None:
        stats = self.stats
        stats.state = LinkState.DISCONNECTED
        stats.losses += 1
        stats.lost_at = time.monotonic()
        stats.last_error = reason
        logger.error("target lost: %s", reason)
        await self.link.lost(reason)
        await self._reconnect()

    async def _reconnect(self) -> None:
        next_pause = self.backoff.pauses()
        while True:
            await asyncio.sleep(next_pause())
            try:
                self.symbol_version = await asyncio.wait_for(
                    self.link.reconnect(), RECONNECT_TIMEOUT_S
                )
            except asyncio.CancelledError:
                raise
            except Exception as error:
                text = (
                    f"{type(error).__name__}: {error}"
                    if str(error)
                    else type(error).__name__
                )
                self.stats.last_error = f"reconnect failed: {text}"
                self._rare_log.info(
                    "reconnect", "target: %s (trying again)", self.stats.last_error
                )
                continue
            self.stats.reconnects += 1
            self._resync_wanted = ""  # the reconnect resolved every symbol
            self._connected()
            return

    def _connected(self) -> None:
        """The end of an outage (a loss, a stop): measured from its start,
        which is then forgotten (a later resync is no outage)."""
        stats = self.stats
        if stats.lost_at:
            stats.last_recovery_s = time.monotonic() - stats.lost_at
            stats.lost_at = 0.0
        stats.state = LinkState.CONNECTED
        if self._first_contact:  # booted without it: the first answer
            self._first_contact = False
            logger.info(
                "target answers: polling (%.1f s after start)", stats.last_recovery_s
            )
            return
        logger.warning(
            "target back: polling again (%.1f s after the loss)",
            stats.last_recovery_s,
        )
