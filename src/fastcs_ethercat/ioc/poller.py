"""Poll one master's points with sum reads and hand on only what changed.

Per cycle: one 0xF080 sum read per <= 500 items, an item per source symbol
read by its handle (`ioc.decode`, `ioc.handles`), each answer decoded with
one numpy view and compared with the previous answer; `on_changes` gets only
changed values (all on the first cycle and after a failure), `on_errors` the
points whose item failed (an invalid handle after an online change among
them), without stopping the others.

Writes go by handle too: `pack_write` checks a value against the point's
type and gives the bytes its handle takes (a bit or bit field: one byte
holding the value, which the target puts into its bits alone).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from fastcs_ethercat.ads.client import AdsClient, AdsError
from fastcs_ethercat.ads.constants import MAX_SUM_SUB_COMMANDS, AdsReturnCode
from fastcs_ethercat.ads.values import array_type_name, pack_value
from fastcs_ethercat.ioc.decode import PollLayout
from fastcs_ethercat.ioc.plan import Point, PointKind

logger = logging.getLogger(__name__)

OnChanges = Callable[[list[tuple[Point, object]], float], object]
"""`on_changes(changes, timestamp)`: (point, value) pairs, time.time() of the read."""
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

    @property
    def mean_cycle_s(self) -> float:
        return self.total_cycle_s / self.cycles if self.cycles else 0.0


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
            stamp = time.time()
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
                self._hand_on(self.on_changes, changes, stamp)
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


INTEGER_RANGES: Final = {
    "SINT": (-(2**7), 2**7 - 1),
    "USINT": (0, 2**8 - 1),
    "BYTE": (0, 2**8 - 1),
    "INT": (-(2**15), 2**15 - 1),
    "UINT": (0, 2**16 - 1),
    "WORD": (0, 2**16 - 1),
    "DINT": (-(2**31), 2**31 - 1),
    "UDINT": (0, 2**32 - 1),
    "DWORD": (0, 2**32 - 1),
    "LINT": (-(2**63), 2**63 - 1),
    "ULINT": (0, 2**64 - 1),
    "LWORD": (0, 2**64 - 1),
}
REAL_MAX: Final = 3.4028234663852886e38


def check_write(point: Point, value: Any) -> None:
    """Refuse (ValueError) a value the point's type cannot hold, before ADS."""
    if point.kind is PointKind.ARRAY:
        values = list(value) if isinstance(value, list | tuple) else None
        if values is None or len(values) != point.length:
            raise ValueError(f"{point.symbol} takes {point.length} values")
        for element in values:
            _check_scalar(point, point.type_name, element)
        return
    if point.kind is PointKind.BIT or point.type_name in ("BOOL", "BIT"):
        if value not in (0, 1) or isinstance(value, float):
            raise ValueError(f"{value!r} is not a boolean for {point.symbol}")
        return
    if point.kind is PointKind.BITS:
        bits = max(point.bit_size, 1)
        if not isinstance(value, int) or not 0 <= value < 1 << bits:
            raise ValueError(f"{value!r} does not fit {bits} bits of {point.symbol}")
        return
    _check_scalar(point, point.type_name, value)


def _check_scalar(point: Point, type_name: str, value: Any) -> None:
    limits = INTEGER_RANGES.get(type_name)
    if limits is not None:
        integral = isinstance(value, int | np.integer) or (
            isinstance(value, float) and value.is_integer()
        )
        if isinstance(value, bool) or not integral:
            raise ValueError(f"{value!r} is not an integer for {point.symbol}")
        low, high = limits
        if not low <= int(value) <= high:
            raise ValueError(
                f"{value!r} is out of range {low}..{high} ({type_name}) "
                f"for {point.symbol}"
            )
    elif type_name in ("REAL", "LREAL"):
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise ValueError(f"{value!r} is not a number for {point.symbol}")
        if not math.isfinite(float(value)):
            raise ValueError(f"{value!r} is not finite for {point.symbol}")
        if type_name == "REAL" and abs(float(value)) > REAL_MAX:
            raise ValueError(f"{value!r} is out of range of REAL for {point.symbol}")


def pack_write(point: Point, value: Any) -> bytes:
    """The bytes a write of `value` to `point`'s handle takes (ValueError if
    its type cannot hold it): a bit or bit field one byte holding the value,
    which the target puts into those bits alone; an oversampling array all
    its elements."""
    check_write(point, value)
    if point.kind in (PointKind.BIT, PointKind.BITS):
        bits = max(point.bit_size, 1)
        number = int(bool(value)) if bits == 1 else int(value)
        return number.to_bytes((bits + 7) // 8, "little")
    type_name = point.type_name
    if point.kind is PointKind.ARRAY:
        type_name = array_type_name(0, point.length - 1, point.type_name)
    return pack_value(type_name, value)
