"""Poll one master's points with sum reads and hand on only what changed.

Per cycle: one 0xF080 sum read per <= 500 items, an item per source symbol
read by its handle (`ioc.decode`, `ioc.handles`), each answer decoded with
one numpy view and compared with the previous answer; `on_changes` gets only
changed values (all on the first cycle and after a failure), `on_errors` the
points whose item failed (an invalid handle after an online change among
them), without stopping the others. The bytes of a write are
`ioc.encode`'s.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from fastcs_ethercat.ads.client import AdsClient, AdsError
from fastcs_ethercat.ads.constants import MAX_SUM_SUB_COMMANDS, AdsReturnCode
from fastcs_ethercat.ioc.decode import PollLayout
from fastcs_ethercat.ioc.plan import Point

logger = logging.getLogger(__name__)

OnChanges = Callable[[list[tuple[Point, object]]], object]
"""`on_changes(changes)`: the (point, value) pairs a read found changed."""
OnErrors = Callable[[list[tuple[Point, int]]], object]
"""`on_errors(errors)`: (point, ADS return code) of points that failed."""


@dataclass(slots=True)
class PollStats:
    """What a poller has done so far."""

    cycles: int = 0
    requests: int = 0
    changes: int = 0
    errors: int = 0
    """Cycles whose read failed as a whole."""
    item_errors: int = 0
    """Point errors reported (per point per cycle)."""
    overruns: int = 0
    """Ticks skipped because a cycle ran past them (skipped, not queued)."""
    last_cycle_s: float = 0.0
    max_cycle_s: float = 0.0
    total_cycle_s: float = 0.0
    last_error: str = ""


class Poller:
    """Polls `points` through `client` (the master's device port), each by
    the handle of its source symbol (`handles`: source name -> handle)."""

    def __init__(
        self,
        client: AdsClient,
        points: Sequence[Point],
        handles: Mapping[str, int],
        on_changes: OnChanges,
        on_errors: OnErrors | None = None,
        *,
        chunk_size: int = MAX_SUM_SUB_COMMANDS,
    ) -> None:
        self.client = client
        self.on_changes = on_changes
        self.on_errors = on_errors
        self.chunk_size = chunk_size
        self.layout = PollLayout.build(points, handles, chunk_size)
        self.stats = PollStats()
        self._items = [item for chunk in self.layout.chunks for item in chunk.items]
        self._stop = asyncio.Event()

    @property
    def points(self) -> list[Point]:
        return self.layout.points

    def invalidate(self) -> None:
        """Report every value again on the next cycle."""
        self.layout.invalidate()

    async def poll_once(self) -> int:
        """One cycle; returns the number of changed values handed on."""
        started = time.perf_counter()
        items = self._items
        changed = 0
        try:
            answers = (
                await self.client.sum_read(items, self.chunk_size) if items else []
            )
        except AdsError as error:
            self._failed(error.code, str(error))
        else:
            self.stats.requests += len(answers)
            changes: list[tuple[Point, object]] = []
            errors: list[tuple[Point, int]] = []
            for chunk, answer in zip(self.layout.chunks, answers, strict=True):
                try:
                    chunk_changes, chunk_errors = chunk.decode(answer)
                except ValueError as error:
                    chunk.invalidate()
                    chunk_errors = [
                        (p, int(AdsReturnCode.DEVICE_INVALID_SIZE))
                        for p in chunk.points
                    ]
                    chunk_changes = []
                    self.stats.last_error = str(error)
                changes += chunk_changes
                errors += chunk_errors
            if changes:
                changed = len(changes)
                self.stats.changes += changed
                self._hand_on(self.on_changes, changes)
            if errors:
                self.stats.item_errors += len(errors)
                self._report(errors)
        elapsed = time.perf_counter() - started
        stats = self.stats
        stats.cycles += 1
        stats.last_cycle_s = elapsed
        stats.total_cycle_s += elapsed
        stats.max_cycle_s = max(stats.max_cycle_s, elapsed)
        return changed

    def _failed(self, code: int, text: str) -> None:
        """The whole read failed: every point is in error, all resent later."""
        self.stats.errors += 1
        self.stats.last_error = text
        self.layout.invalidate()
        self._report([(point, code) for point in self.layout.points])

    def _report(self, errors: list[tuple[Point, int]]) -> None:
        if self.on_errors is not None:
            self._hand_on(self.on_errors, errors)

    def _hand_on(self, callback: Callable[..., object], *args: Any) -> None:
        """Call back; a failing consumer must not stop the polling."""
        try:
            callback(*args)
        except Exception as error:
            self.stats.last_error = f"{type(error).__name__} in callback: {error}"
            logger.exception("poller callback failed")

    async def run(self, rate_hz: float) -> None:
        """Poll at `rate_hz` on a fixed time grid until `stop()`.

        Ticks are start + k * period (no drift); a cycle that overruns skips
        the ticks it missed and counts an overrun.
        """
        period = 1.0 / rate_hz
        loop = asyncio.get_running_loop()
        start = loop.time()
        tick = 0
        self._stop.clear()
        while not self._stop.is_set():
            await self.poll_once()
            tick += 1
            due = start + tick * period
            now = loop.time()
            if now > due:
                missed = int((now - due) // period) + 1
                self.stats.overruns += missed
                tick += missed
                due = start + tick * period
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._stop.wait(), due - loop.time())

    def stop(self) -> None:
        self._stop.set()
