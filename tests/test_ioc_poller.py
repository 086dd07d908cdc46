"""The poller against the simulator (real subprocess, real pyads): sum reads,
changed values only, per-item errors, writes and the timed loop."""

from __future__ import annotations

import asyncio
import math
from collections.abc import AsyncIterator, Iterator
from dataclasses import replace

import numpy as np
import pytest

from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.decode import PollLayout
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.plan import Point, PointKind, SystemPlan
from fastcs_ethercat.ioc.poller import Poller
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals import load_terminals
from tests.conftest import REPO_ROOT, TERMINALS_DIR

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
SUM_READ = "0xF080"


class Recorder:
    """Collects what the poller hands on."""

    def __init__(self) -> None:
        self.changes: list[list[tuple[Point, object]]] = []
        self.errors: list[list[tuple[Point, int]]] = []

    def on_changes(self, changes: list[tuple[Point, object]], stamp: float) -> None:
        assert stamp > 0
        self.changes.append(changes)

    def on_errors(self, errors: list[tuple[Point, int]]) -> None:
        self.errors.append(errors)

    def last(self) -> dict[str, object]:
        return {p.key: v for p, v in self.changes[-1]} if self.changes else {}


@pytest.fixture(scope="module")
def sim() -> Iterator[SimProcess]:
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR) as process:
        yield process


@pytest.fixture(scope="module")
def plan(sim: SimProcess) -> SystemPlan:
    async def run() -> SystemPlan:
        config = IocConfig(prefix="TEST", target=sim.pyads_ip, ams_net_id=sim.net_id)
        async with ClientPool.for_target(config.target) as pool:
            return await discover(pool, load_terminals([TERMINALS_DIR]), config)

    return asyncio.run(run())


@pytest.fixture
async def client(sim: SimProcess, plan: SystemPlan) -> AsyncIterator[AdsClient]:
    async with ClientPool(sim.host, sim.tcp_port) as pool:
        yield await pool.get(sim.net_id, plan.masters[0].symbol_port)
    sim.clear_faults()


def all_points(plan: SystemPlan) -> list[Point]:
    master = plan.masters[0]
    return [p for t in master.terminals for p in t.points] + master.master_points


def by_key(plan: SystemPlan) -> dict[str, Point]:
    return {p.key: p for p in all_points(plan)}


def key(symbol: str) -> str:
    return f"Device 1 (EtherCAT)/{symbol}"


@pytest.mark.e2e
async def test_one_sum_read_per_cycle(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)
    poller = Poller(client, points, Recorder().on_changes)
    assert poller.layout.item_count < len(points)  # shared words read once
    sim.reset_counters()
    await poller.poll_once()
    counters = sim.counters()
    assert counters["index_groups"] == {SUM_READ: 1}
    assert counters["total"] == math.ceil(len(points) / 500) == 1
    assert poller.stats.requests == poller.stats.requests_per_cycle == 1


@pytest.mark.e2e
async def test_more_than_500_points_in_500_item_requests(
    sim: SimProcess, client: AdsClient
) -> None:
    """1 200 single bits of the input bit image: 1 200 items, 3 requests."""
    points = [
        Point(f"bit{n}", f"bit{n}", f"bit{n}", "BIT", PointKind.BIT, 0xF031, n, 1)
        for n in range(1200)
    ]
    recorder = Recorder()
    poller = Poller(client, points, recorder.on_changes, recorder.on_errors)
    sim.reset_counters()
    await poller.poll_once()
    assert sim.counters()["index_groups"] == {SUM_READ: math.ceil(1200 / 500)}
    assert recorder.errors == []
    assert len(recorder.changes[0]) == 1200


@pytest.mark.e2e
async def test_requests_split_at_the_chunk_size(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)
    poller = Poller(client, points, Recorder().on_changes, chunk_size=25)
    sim.reset_counters()
    await poller.poll_once()
    requests = sim.counters()["index_groups"][SUM_READ]
    assert requests == math.ceil(poller.layout.item_count / 25)
    assert requests <= math.ceil(len(points) / 25)


@pytest.mark.e2e
async def test_first_cycle_all_then_only_changes(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)
    recorder = Recorder()
    poller = Poller(client, points, recorder.on_changes, recorder.on_errors)
    await poller.poll_once()
    assert {p.key for p, _ in recorder.changes[0]} == {p.key for p in points}
    assert recorder.errors == []
    target = "Term 22 (EL3104).AI Standard Channel 1"
    sim.set_symbol(target, {"Status": {"Overrange": True}, "Value": 4321})
    await poller.poll_once()
    changed = recorder.last()
    assert changed[key(f"{target}.Value")] == 4321
    assert changed[key(f"{target}.Status.Overrange")] is True
    assert key(f"{target}.Status.Underrange") not in changed
    assert len(changed) < len(points) / 2
    # Nothing forced changed since: the forced values are not sent again.
    recorder.changes.clear()
    await poller.poll_once()
    assert key(f"{target}.Value") not in recorder.last()
    assert key(f"{target}.Status.Overrange") not in recorder.last()


@pytest.mark.e2e
async def test_values_follow_the_signals(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    sine = key("Term 5 (EL3104).AI Compact Channel 1")
    points = [by_key(plan)[sine]]
    recorder = Recorder()
    poller = Poller(client, points, recorder.on_changes)
    seen: list[object] = []
    for _ in range(5):
        await poller.poll_once()
        seen.append(recorder.last().get(sine))
        await asyncio.sleep(0.05)
    values = [v for v in seen if v is not None]
    assert len(set(values)) >= 3
    assert all(isinstance(v, int) and -20000 <= v <= 20000 for v in values)
    now = sim.get_symbol("Term 5 (EL3104).AI Compact Channel 1")
    assert -20000 <= now <= 20000


@pytest.mark.e2e
async def test_arrays_bits_and_counters_decoded(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = by_key(plan)
    chosen = [
        points[key("Term 14 (EL3702).Ch1 Sample 0")],
        points[key("Term 2 (EL1014).Channel 3")],
        points[key("Term 8 (EL1502).CNT Inputs Channel 2.Counter value")],
    ]
    sim.set_symbol("Term 2 (EL1014).Channel 3", True)
    sim.set_symbol("Term 14 (EL3702).Ch1 Sample 0", list(range(-5, 5)))
    recorder = Recorder()
    await Poller(client, chosen, recorder.on_changes).poll_once()
    values = recorder.last()
    samples = values[chosen[0].key]
    assert isinstance(samples, np.ndarray)
    assert samples.tolist() == list(range(-5, 5))
    assert values[chosen[1].key] is True
    assert isinstance(values[chosen[2].key], int)


@pytest.mark.e2e
async def test_item_errors_do_not_stop_the_others(
    plan: SystemPlan, client: AdsClient
) -> None:
    good = all_points(plan)[:20]
    bad = replace(good[0], key="bad", symbol="bad", index_offset=1_000_000)
    recorder = Recorder()
    poller = Poller(client, [*good, bad], recorder.on_changes, recorder.on_errors)
    await poller.poll_once()
    assert {p.key for p, _ in recorder.changes[0]} == {p.key for p in good}
    [errors] = recorder.errors
    assert [(p.key, code != 0) for p, code in errors] == [("bad", True)]
    assert poller.stats.item_errors == 1


@pytest.mark.e2e
async def test_whole_read_failure_reported_then_recovered(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)[:10]
    recorder = Recorder()
    poller = Poller(client, points, recorder.on_changes, recorder.on_errors)
    await poller.poll_once()
    sim.add_fault("error", code=0x708, group=0xF080)
    await poller.poll_once()
    assert poller.stats.errors == 1
    assert {p.key for p, _ in recorder.errors[-1]} == {p.key for p in points}
    assert all(code == 0x708 for _, code in recorder.errors[-1])
    sim.clear_faults()
    await poller.poll_once()
    assert {p.key for p, _ in recorder.changes[-1]} == {p.key for p in points}


@pytest.mark.e2e
async def test_writes_reach_the_simulator(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = by_key(plan)
    poller = Poller(client, list(points.values()), Recorder().on_changes)
    await poller.write_point(points[key("Term 6 (EL2024).Channel 2")], True)
    assert sim.get_symbol("Term 6 (EL2024).Channel 2") is True
    assert sim.get_symbol("Term 6 (EL2024).Channel 1") is False
    await poller.write_point(points[key("Term 15 (EL4134).AO Output Channel 3")], -1000)
    assert sim.get_symbol("Term 15 (EL4134).AO Output Channel 3") == -1000
    outputs = "Term 8 (EL1502).CNT Outputs Channel 1"
    await poller.write_point(points[key(f"{outputs}.Control.Set counter")], True)
    await poller.write_point(points[key(f"{outputs}.Control.Set output")], True)
    await poller.write_point(points[key(f"{outputs}.Set counter value")], 4242)
    await poller.write_point(points[key(f"{outputs}.Control.Set output")], False)
    state = sim.get_symbol(outputs)
    assert state["Control"]["Set counter"] is True
    assert state["Control"]["Set output"] is False
    assert state["Set counter value"] == 4242
    samples = list(range(100, 110))
    await poller.write_point(points[key("Term 16 (EL4732).Ch2 Sample 0")], samples)
    assert sim.get_symbol("Term 16 (EL4732).Ch2 Sample 0") == samples


@pytest.mark.e2e
async def test_run_keeps_its_rate(plan: SystemPlan, client: AdsClient) -> None:
    recorder = Recorder()
    poller = Poller(client, all_points(plan), recorder.on_changes)
    task = asyncio.create_task(poller.run(50.0))
    await asyncio.sleep(0.5)
    poller.stop()
    await asyncio.wait_for(task, 2)
    stats = poller.stats
    # 25 ticks in 0.5 s; ticks missed under load are skipped, not queued.
    assert 5 <= stats.cycles <= 27
    assert stats.cycles + stats.overruns <= 28
    assert stats.requests == stats.cycles
    assert stats.mean_cycle_s > 0
    assert stats.max_cycle_s >= stats.mean_cycle_s


def synthetic(
    symbol: str,
    offset: int,
    size: int,
    kind: PointKind = PointKind.SCALAR,
    bit_offset: int = 0,
    bit_size: int = 0,
) -> Point:
    scalar = {1: "USINT", 2: "INT", 4: "DINT"}[size]
    type_name = scalar if kind is PointKind.SCALAR else "BIT"
    return Point(
        symbol,
        symbol,
        symbol,
        type_name,
        kind,
        0xF030,
        offset,
        size,
        bit_offset=bit_offset,
        bit_size=bit_size,
    )


def test_layout_merges_shared_bytes_only() -> None:
    word_bits = [
        synthetic(f"b{n}", 10, 2, PointKind.BIT, bit_offset=n, bit_size=1)
        for n in (0, 9, 15)
    ]
    value = synthetic("v", 12, 2)
    inside = synthetic("inside", 11, 1)
    wc = [
        replace(synthetic(f"wc{n}", 7, 1, PointKind.BIT), index_group=0xF031)
        for n in range(3)
    ]
    layout = PollLayout.build([*word_bits, value, inside, *wc])
    items = [
        (i.index_group, i.index_offset, i.length)
        for c in layout.chunks
        for i in c.items
    ]
    # Bits of one word and a byte inside it: one item; the adjacent value is
    # its own item; the WcState bit many terminals share is read once.
    assert items == [(0xF030, 10, 2), (0xF030, 12, 2), (0xF031, 7, 1)]


def test_decode_reports_only_changed_bits_and_values() -> None:
    bits = [
        synthetic(f"b{n}", 0, 2, PointKind.BIT, bit_offset=n, bit_size=1)
        for n in (1, 8, 15)
    ]
    field = synthetic("f", 0, 2, PointKind.BITS, bit_offset=6, bit_size=3)
    value = synthetic("v", 2, 2)
    layout = PollLayout.build([*bits, field, value])
    [chunk] = layout.chunks

    def answer(word: int, number: int) -> bytes:
        head = bytes(4 * len(chunk.items))
        return (
            head
            + word.to_bytes(2, "little")
            + number.to_bytes(2, "little", signed=True)
        )

    changes, errors = chunk.decode(answer(0b1000_0001_1100_0010, -7))
    assert errors == []
    assert {p.key: v for p, v in changes} == {
        "b1": True,
        "b8": True,
        "b15": True,
        "f": 0b111,
        "v": -7,
    }
    # Bit 0 and bit 14 flip: none of the served bits changed; the value did.
    changes, _ = chunk.decode(answer(0b1100_0001_1100_0011, 5))
    assert [(p.key, v) for p, v in changes] == [("v", 5)]
    changes, _ = chunk.decode(answer(0b1100_0001_1100_0011, 5))
    assert changes == []
