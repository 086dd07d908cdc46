"""The CA client side: connect, count monitor events, time one change.

Runs in the bench process on its asyncio loop (aioca); the loopback EPICS
environment must be in `os.environ` before the first call.
"""

from __future__ import annotations

import asyncio
import random
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

from aioca import camonitor, connect


async def connect_all(names: Sequence[str], deadline: float) -> float | None:
    """Monotonic time at which every PV was connected (None: not by `deadline`)."""
    pending = list(names)
    while pending:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        results = await connect(pending, timeout=min(left, 5.0), throw=False)
        pending = [n for n, r in zip(pending, results, strict=True) if not r.ok]
    return time.monotonic()


async def updates_per_second(
    names: Sequence[str], seconds: float, *, warmup_s: float = 1.0
) -> float:
    """Monitor events per second received for `names` over `seconds`."""
    count = [0]

    def on_update(value: Any, index: int) -> None:
        count[0] += 1

    subscriptions = camonitor(list(names), on_update, all_updates=True)
    try:
        await connect(list(names), timeout=30.0, throw=False)
        await asyncio.sleep(warmup_s)
        first, start = count[0], time.monotonic()
        await asyncio.sleep(seconds)
        return (count[0] - first) / (time.monotonic() - start)
    finally:
        for subscription in subscriptions:
            subscription.close()


async def change_latencies_ms(
    pv: str,
    change: Callable[[int], object],
    *,
    samples: int,
    period_s: float,
    timeout_s: float = 5.0,
) -> tuple[list[float], list[float]]:
    """From the change to the CA monitor event carrying it, once per sample,
    and the round trip of each change call.

    `change(value)` is a blocking call that sets the simulated value; the
    change counts as made at the midpoint of that call (within half its round
    trip). Each sample starts at a random phase of the poll period."""
    loop = asyncio.get_running_loop()
    waiting: dict[int, asyncio.Future[float]] = {}

    def on_update(value: Any) -> None:
        future = waiting.pop(int(value), None)
        if future is not None and not future.done():
            future.set_result(time.perf_counter())

    subscription = camonitor(pv, on_update, all_updates=True)
    try:
        await connect(pv, timeout=10.0)
        await asyncio.sleep(2 * period_s + 0.2)
        latencies: list[float] = []
        round_trips: list[float] = []
        for sample in range(samples):
            value = 1000 + sample % 20000
            future: asyncio.Future[float] = loop.create_future()
            waiting[value] = future
            await asyncio.sleep(random.uniform(0.0, period_s))
            sent = time.perf_counter()
            await asyncio.to_thread(change, value)
            returned = time.perf_counter()
            received = await asyncio.wait_for(future, timeout_s)
            latencies.append((received - (sent + returned) / 2) * 1000.0)
            round_trips.append((returned - sent) * 1000.0)
        return latencies, round_trips
    finally:
        subscription.close()


def percentiles(values: Sequence[float]) -> dict[str, float]:
    """Median and 99th percentile (nearest rank), in the values' unit."""
    ordered = sorted(values)
    p99 = ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))]
    return {"p50": round(statistics.median(ordered), 2), "p99": round(p99, 2)}
