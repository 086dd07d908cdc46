"""Poller hot path: decode + diff of one cycle for 1 000 / 5 000 / 10 000 points.

Usage: python benchmarks/bench_poll.py [--runs N] [--live]

Points mimic a real rack, each read by the handle of its symbol: per 4-byte
analog channel one symbol, a status word (8 bit points) and an INT value;
per 16 channels 16 digital bit symbols; a few oversampled arrays. For each
size it prints the sum-read items and requests per cycle and the median time
of `decode` over all requests when nothing changed, when 1 % of the bytes
changed and when everything changed (every value converted and handed on).
With --live it also polls the demo chain in the simulator and prints the
median full cycle (sum read round trip + decode).
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from pathlib import Path

import numpy as np

from fastcs_ethercat.ads.constants import IndexGroup
from fastcs_ethercat.ioc.decode import PollLayout
from fastcs_ethercat.ioc.plan import Point, PointKind, Source

REPO = Path(__file__).resolve().parents[1]
BYTES = IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES
BITS = IndexGroup.IO_IMAGE_RW_OUTPUT_BITS


def synthetic_points(count: int) -> list[Point]:
    """`count` points laid out like analog channels, digital bits and arrays."""
    points: list[Point] = []
    offset = bit = 0
    while len(points) < count:
        kind = len(points) % 40
        if kind < 27:  # an analog channel: 8 status bits + value
            channel = f"c{offset}"
            for n in range(8):
                points.append(
                    Point(
                        f"k{len(points)}",
                        f"s{len(points)}",
                        f"a{len(points)}",
                        "BIT",
                        PointKind.BIT,
                        BYTES,
                        offset,
                        2,
                        bit_offset=n * 2,
                        bit_size=1,
                        source=Source(channel),
                    )
                )
            points.append(
                Point(
                    f"k{len(points)}",
                    f"s{len(points)}",
                    f"a{len(points)}",
                    "INT",
                    PointKind.SCALAR,
                    BYTES,
                    offset + 2,
                    2,
                    source=Source(channel, 2),
                )
            )
            offset += 4
        elif kind < 39:
            points.append(
                Point(
                    f"k{len(points)}",
                    f"s{len(points)}",
                    f"a{len(points)}",
                    "BIT",
                    PointKind.BIT,
                    BITS,
                    bit,
                    1,
                    bit_size=1,
                )
            )
            bit += 1
        else:
            points.append(
                Point(
                    f"k{len(points)}",
                    f"s{len(points)}",
                    f"a{len(points)}",
                    "INT",
                    PointKind.ARRAY,
                    BYTES,
                    offset,
                    20,
                    length=10,
                )
            )
            offset += 20
    return points[:count]


def answers_for(layout: PollLayout, rng: np.random.Generator) -> list[np.ndarray]:
    """Random answers with every item result 0."""
    answers = []
    for chunk in layout.chunks:
        raw = rng.integers(0, 256, chunk.answer_size, dtype=np.uint8)
        raw[: 4 * len(chunk.items)] = 0
        answers.append(raw)
    return answers


def time_decode(layout: PollLayout, answers: list[bytes], runs: int) -> float:
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        for chunk, answer in zip(layout.chunks, answers, strict=True):
            chunk.decode(answer)
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def bench_size(count: int, runs: int) -> None:
    rng = np.random.default_rng(1)
    points = synthetic_points(count)
    handles = {name: n for n, name in enumerate({p.source_name for p in points})}
    layout = PollLayout.build(points, handles)
    base = answers_for(layout, rng)
    for chunk, answer in zip(layout.chunks, base, strict=True):
        chunk.decode(answer.tobytes())  # first cycle: everything
    same = [a.tobytes() for a in base]
    time_decode(layout, same, 3)
    unchanged = time_decode(layout, same, runs)
    some = []
    for chunk, answer in zip(layout.chunks, base, strict=True):
        changed = answer.copy()
        head = 4 * len(chunk.items)
        picks = rng.choice(np.arange(head, len(changed)), max(1, len(changed) // 100))
        changed[picks] ^= 0xFF
        some.append(changed.tobytes())
    one_percent = statistics.median(_alternate(layout, same, some) for _ in range(runs))
    full = [
        bytes(4 * len(c.items)) + (~a[4 * len(c.items) :]).tobytes()
        for c, a in zip(layout.chunks, base, strict=True)
    ]
    all_changed = statistics.median(_alternate(layout, same, full) for _ in range(runs))
    print(
        f"{count:>6} points  {sum(len(c.items) for c in layout.chunks):>5} items  "
        f"{len(layout.chunks):>3} requests/cycle  "
        f"decode+diff: unchanged {unchanged * 1e3:7.3f} ms  "
        f"1% changed {one_percent * 1e3:7.3f} ms  "
        f"all changed {all_changed * 1e3:7.3f} ms"
    )


def _alternate(layout: PollLayout, before: list[bytes], after: list[bytes]) -> float:
    """Time one cycle that sees `after` following `before`."""
    for chunk, answer in zip(layout.chunks, before, strict=True):
        chunk.decode(answer)
    started = time.perf_counter()
    for chunk, answer in zip(layout.chunks, after, strict=True):
        chunk.decode(answer)
    return time.perf_counter() - started


def bench_live(runs: int) -> None:
    from fastcs_ethercat.ioc.clients import ClientPool
    from fastcs_ethercat.ioc.config import IocConfig
    from fastcs_ethercat.ioc.discovery import discover
    from fastcs_ethercat.ioc.handles import acquire
    from fastcs_ethercat.ioc.poller import Poller
    from fastcs_ethercat.sim.process import SimProcess
    from fastcs_ethercat.terminals import load_terminals

    async def run(sim: SimProcess) -> None:
        config = IocConfig(prefix="BENCH", target=sim.pyads_ip, ams_net_id=sim.net_id)
        async with ClientPool(config.target_host, config.target_port) as pool:
            plan = await discover(pool, load_terminals([REPO / "terminals"]), config)
            master = plan.masters[0]
            points = [p for t in master.terminals for p in t.points]
            client = await pool.get(plan.net_id, master.symbol_port)
            handles = await acquire(client, points)
            poller = Poller(client, points, handles.reads, lambda changes: None)
            times = []
            for _ in range(runs):
                started = time.perf_counter()
                await poller.poll_once()
                times.append(time.perf_counter() - started)
            items = sum(len(chunk.items) for chunk in poller.layout.chunks)
            print(
                f"live demo chain: {len(points)} points, {items} items, median cycle "
                f"{statistics.median(times) * 1e3:.3f} ms over {runs} cycles"
            )

    with SimProcess(REPO / "ioc" / "demo-chain.yaml") as sim:
        asyncio.run(run(sim))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--live", action="store_true")
    args = parser.parse_args()
    for count in (1_000, 5_000, 10_000):
        bench_size(count, args.runs)
    if args.live:
        bench_live(args.runs)


if __name__ == "__main__":
    main()
