"""The IOC's asyncio ADS client against the pyads path it replaced, side by side.

Usage: python benchmarks/bench_ads_client.py [--requests N] [--seconds S]

Both talk to one simulator process (`ioc/demo-chain.yaml` plus digital inputs
up to ~500 symbols) on loopback. The pyads path is what the IOC did before:
a `pyads.Connection` (Beckhoff's AdsLib) whose calls run on one worker
thread, results handed back to the event loop. Printed per path:

- one 0xF080 sum read of 500 symbols, one request at a time: latency p50 /
  p99, requests per second, client CPU per request;
- the same with 8 callers at once (the pyads path queues them on its thread,
  the asyncio client has them all in flight);
- 50 notifications (cyclic, 10 ms: 5 000 samples a second) for S seconds:
  samples per second received and client CPU.
"""

from __future__ import annotations

import argparse
import asyncio
import ctypes
import statistics
import time
from collections.abc import Awaitable, Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pyads
import yaml
from pyads.constants import ADSIGRP_SUMUP_READ
from pyads.structs import SAdsNotificationHeader, SAdsSumRequest

from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ads.constants import IndexGroup, TransmissionMode
from fastcs_ethercat.ads.sums import SumReadItem
from fastcs_ethercat.sim.process import SimProcess

REPO = Path(__file__).resolve().parents[1]
NET_ID = "192.0.2.77.1.1"
DEVICE_PORT = 27905
SYMBOLS = 500
NOTIFICATIONS = 50
CALLERS = 8
BIT_GROUPS = {IndexGroup.IO_IMAGE_RW_INPUT_BITS, IndexGroup.IO_IMAGE_RW_OUTPUT_BITS}


class PyadsPath:
    """The old path: pyads on one worker thread per connection."""

    def __init__(self, ip: str) -> None:
        self.connection = pyads.Connection(NET_ID, DEVICE_PORT, ip)
        self.executor = ThreadPoolExecutor(max_workers=1)
        self.handles: list[tuple[int, int]] = []

    async def __aenter__(self) -> PyadsPath:
        await self._run(self.connection.open)
        return self

    async def __aexit__(self, *_: object) -> None:
        def close() -> None:
            for handle in self.handles:
                self.connection.del_device_notification(*handle)
            self.connection.close()

        await self._run(close)
        self.executor.shutdown()

    async def _run(self, job: Callable[[], Any]) -> Any:
        return await asyncio.get_running_loop().run_in_executor(self.executor, job)

    async def sum_read(self, items: Sequence[SumReadItem]) -> bytes:
        requests = (SAdsSumRequest * len(items))()
        for request, item in zip(requests, items, strict=True):
            request.iGroup = item.index_group
            request.iOffset = item.index_offset
            request.size = item.length

        def read() -> bytes:
            raw = self.connection.read_write(
                ADSIGRP_SUMUP_READ, len(items), None, requests, None, return_ctypes=True
            )
            return bytes(raw)

        return await self._run(read)

    async def subscribe(self, item: SumReadItem, on_sample: Callable[[], None]) -> None:
        loop = asyncio.get_running_loop()
        attributes = pyads.NotificationAttrib(
            item.length, int(TransmissionMode.SERVER_CYCLE), cycle_time=10.0
        )

        def callback(pointer: Any, _: Any) -> None:
            header = pointer.contents
            ctypes.string_at(
                ctypes.addressof(header) + SAdsNotificationHeader.data.offset,
                header.cbSampleSize,
            )
            loop.call_soon_threadsafe(on_sample)

        handles = await self._run(
            lambda: self.connection.add_device_notification(
                (item.index_group, item.index_offset), attributes, callback
            )
        )
        self.handles.append(handles)


class AsyncioPath:
    """The new path: the project's own asyncio client."""

    def __init__(self, port: int) -> None:
        self.client = AdsClient("127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=port)

    async def __aenter__(self) -> AsyncioPath:
        await self.client.open()
        return self

    async def __aexit__(self, *_: object) -> None:
        await self.client.close()

    async def sum_read(self, items: Sequence[SumReadItem]) -> bytes:
        return (await self.client.sum_read(items))[0]

    async def subscribe(self, item: SumReadItem, on_sample: Callable[[], None]) -> None:
        await self.client.add_notification(
            item.index_group,
            item.index_offset,
            item.length,
            lambda _: on_sample(),
            mode=TransmissionMode.SERVER_CYCLE,
            cycle_time_ms=10.0,
        )


def write_chain(path: Path) -> Path:
    chain = yaml.safe_load((REPO / "ioc" / "demo-chain.yaml").read_text())
    chain["system"]["net_id"] = NET_ID
    chain["masters"][0]["slaves"] += [{"type": "EL1014"}] * 80
    path.write_text(yaml.safe_dump(chain, sort_keys=False))
    return path


async def symbol_items(port: int) -> list[SumReadItem]:
    async with AdsClient("127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=port) as client:
        tables = await client.upload_symbols()
    items = [
        SumReadItem(s.index_group, s.index_offset, max(s.size, 1))
        for s in tables.symbols
        if s.size <= 64
    ]
    if len(items) < SYMBOLS:
        raise SystemExit(f"the chain has {len(items)} symbols, {SYMBOLS} wanted")
    return items[:SYMBOLS]


async def sequential(
    read: Callable[[], Awaitable[bytes]], count: int
) -> tuple[list[float], float, float]:
    """Latencies of `count` reads one after another, wall and CPU time."""
    for _ in range(20):
        await read()
    latencies: list[float] = []
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(count):
        started = time.perf_counter()
        await read()
        latencies.append(time.perf_counter() - started)
    return latencies, time.perf_counter() - wall, time.process_time() - cpu


async def concurrent(read: Callable[[], Awaitable[bytes]], count: int) -> float:
    """Requests per second with CALLERS callers reading at once."""

    async def caller() -> None:
        for _ in range(count // CALLERS):
            await read()

    started = time.perf_counter()
    await asyncio.gather(*(caller() for _ in range(CALLERS)))
    return (count // CALLERS * CALLERS) / (time.perf_counter() - started)


async def notifications(
    path: PyadsPath | AsyncioPath, items: Sequence[SumReadItem], seconds: float
) -> tuple[float, float]:
    """Samples per second received and client CPU (% of a core)."""
    received = [0]

    def on_sample() -> None:
        received[0] += 1

    chosen = [i for i in items if i.index_group not in BIT_GROUPS][:NOTIFICATIONS]
    for item in chosen:
        await path.subscribe(item, on_sample)
    await asyncio.sleep(1.0)
    received[0] = 0
    cpu, wall = time.process_time(), time.perf_counter()
    await asyncio.sleep(seconds)
    elapsed = time.perf_counter() - wall
    return received[0] / elapsed, 100 * (time.process_time() - cpu) / elapsed


async def measure(
    name: str,
    make: Callable[[], PyadsPath | AsyncioPath],
    items: list[SumReadItem],
    count: int,
    seconds: float,
) -> dict[str, float]:
    async with make() as path:
        latencies, wall, cpu = await sequential(lambda: path.sum_read(items), count)
        parallel = await concurrent(lambda: path.sum_read(items), count)
    async with make() as path:
        samples, notify_cpu = await notifications(path, items, seconds)
    latencies.sort()
    figures = {
        "p50_ms": 1e3 * statistics.median(latencies),
        "p99_ms": 1e3 * latencies[int(0.99 * (len(latencies) - 1))],
        "requests_per_s": count / wall,
        "cpu_us_per_request": 1e6 * cpu / count,
        "parallel_requests_per_s": parallel,
        "samples_per_s": samples,
        "notification_cpu_percent": notify_cpu,
    }
    print(f"  measured {name}", flush=True)
    return figures


def report(results: dict[str, dict[str, float]]) -> None:
    rows = [
        ("sum read of 500 symbols, p50 latency", "p50_ms", "ms", 3),
        ("sum read of 500 symbols, p99 latency", "p99_ms", "ms", 3),
        ("sum reads per second, one at a time", "requests_per_s", "/s", 0),
        ("client CPU per sum read", "cpu_us_per_request", "us", 0),
        (
            f"sum reads per second, {CALLERS} callers",
            "parallel_requests_per_s",
            "/s",
            0,
        ),
        (
            f"notifications per second ({NOTIFICATIONS} at 10 ms)",
            "samples_per_s",
            "/s",
            0,
        ),
        ("client CPU while notified", "notification_cpu_percent", "%", 1),
    ]
    names = list(results)
    print(f"{'':58} " + " ".join(f"{n:>12}" for n in names))
    for label, key, unit, digits in rows:
        cells = " ".join(f"{results[n][key]:>10.{digits}f}{unit:>2}" for n in names)
        print(f"{label:58} {cells}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--requests", type=int, default=2000)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        chain = write_chain(Path(folder) / "chain.yaml")
        with SimProcess(chain, terminals=REPO / "terminals") as sim:
            items = asyncio.run(symbol_items(sim.tcp_port))
            results = {
                "pyads": asyncio.run(
                    measure(
                        "pyads",
                        lambda: PyadsPath(sim.pyads_ip),
                        items,
                        args.requests,
                        args.seconds,
                    )
                ),
                "asyncio": asyncio.run(
                    measure(
                        "asyncio",
                        lambda: AsyncioPath(sim.tcp_port),
                        items,
                        args.requests,
                        args.seconds,
                    )
                ),
            }
    report(results)


if __name__ == "__main__":
    main()
