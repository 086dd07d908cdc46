"""The poller against the simulator (a real subprocess): sum reads by symbol
handle, changed values only, per-item errors, handles an online change
invalidates, writes by handle and the timed loop."""

from __future__ import annotations

import asyncio
import math
from collections.abc import AsyncIterator, Iterator
from dataclasses import replace

import numpy as np
import pytest

from fastcs_ethercat.ads.client import AdsClient, AdsHandleInvalidError
from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.decode import PollLayout
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.encode import pack_write
from fastcs_ethercat.ioc.handles import PointHandles, acquire
from fastcs_ethercat.ioc.plan import Point, PointKind, Source, SystemPlan
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

    def on_changes(self, changes: list[tuple[Point, object]]) -> None:
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
        async with ClientPool(config.target_host, config.target_port) as pool:
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


def items_of(layout: PollLayout) -> int:
    """Sum-read items of every request of `layout` (one per source symbol)."""
    return sum(len(chunk.items) for chunk in layout.chunks)


def key(symbol: str) -> str:
    return f"Device 1 (EtherCAT)/{symbol}"


async def poller_of(
    client: AdsClient, points: list[Point], recorder: Recorder, **options: int
) -> Poller:
    """A poller of `points` by freshly taken handles (every one must have one)."""
    handles = await acquire(client, points)
    assert handles.problems == {}
    return Poller(
        client,
        points,
        handles.reads,
        recorder.on_changes,
        recorder.on_errors,
        **options,
    )


async def write(
    client: AdsClient, handles: PointHandles, point: Point, value: object
) -> None:
    await client.write_by_handle(handles.writes[point.symbol], pack_write(point, value))


@pytest.mark.e2e
async def test_one_sum_read_per_cycle(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)
    poller = await poller_of(client, points, Recorder())
    sources = {p.source_name for p in points}
    assert items_of(poller.layout) == len(sources) < len(points)  # a symbol once
    sim.reset_counters()
    await poller.poll_once()
    counters = sim.counters()
    assert counters["index_groups"] == {SUM_READ: 1}
    assert counters["total"] == math.ceil(len(points) / 500) == 1
    assert poller.stats.requests == len(poller.layout.chunks) == 1


@pytest.mark.e2e
async def test_more_than_500_points_in_500_item_requests(
    sim: SimProcess, client: AdsClient
) -> None:
    """1 200 handles the target never gave: 1 200 items in 3 requests, each
    answered with its own error."""
    points = [
        Point(f"bit{n}", f"bit{n}", f"bit{n}", "BIT", PointKind.BIT, 0xF031, n, 1)
        for n in range(1200)
    ]
    recorder = Recorder()
    handles = {f"bit{n}": 0x7000_0000 + n for n in range(1200)}
    poller = Poller(client, points, handles, recorder.on_changes, recorder.on_errors)
    sim.reset_counters()
    await poller.poll_once()
    assert sim.counters()["index_groups"] == {SUM_READ: math.ceil(1200 / 500)}
    assert recorder.changes == []
    [errors] = recorder.errors
    assert len(errors) == 1200
    assert {code for _, code in errors} == {AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND}


@pytest.mark.e2e
async def test_requests_split_at_the_chunk_size(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)
    poller = await poller_of(client, points, Recorder(), chunk_size=25)
    sim.reset_counters()
    await poller.poll_once()
    requests = sim.counters()["index_groups"][SUM_READ]
    assert requests == math.ceil(items_of(poller.layout) / 25)
    assert requests <= math.ceil(len(points) / 25)


@pytest.mark.e2e
async def test_first_cycle_all_then_only_changes(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = all_points(plan)
    recorder = Recorder()
    poller = await poller_of(client, points, recorder)
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
    poller = await poller_of(client, points, recorder)
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
    await (await poller_of(client, chosen, recorder)).poll_once()
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
    bad = replace(good[0], key="bad", symbol="bad", source=Source("bad"))
    recorder = Recorder()
    handles = (await acquire(client, good)).reads | {"bad": 0x7FFF_FFFF}
    poller = Poller(
        client, [*good, bad], handles, recorder.on_changes, recorder.on_errors
    )
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
    poller = await poller_of(client, points, recorder)
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
async def test_writes_by_handle_reach_only_their_own_bits(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    points = by_key(plan)
    handles = await acquire(client, list(points.values()))
    await write(client, handles, points[key("Term 6 (EL2024).Channel 2")], True)
    assert sim.get_symbol("Term 6 (EL2024).Channel 2") is True
    assert sim.get_symbol("Term 6 (EL2024).Channel 1") is False
    analog = points[key("Term 15 (EL4134).AO Output Channel 3")]
    await write(client, handles, analog, -1000)
    assert sim.get_symbol("Term 15 (EL4134).AO Output Channel 3") == -1000
    outputs = "Term 8 (EL1502).CNT Outputs Channel 1"
    # Bits of one control word, each by its own handle: no read-modify-write.
    await write(client, handles, points[key(f"{outputs}.Control.Set counter")], True)
    await write(client, handles, points[key(f"{outputs}.Control.Set output")], True)
    await write(client, handles, points[key(f"{outputs}.Set counter value")], 4242)
    await write(client, handles, points[key(f"{outputs}.Control.Set output")], False)
    state = sim.get_symbol(outputs)
    assert state["Control"]["Set counter"] is True
    assert state["Control"]["Set output"] is False
    assert state["Set counter value"] == 4242
    samples = list(range(100, 110))
    await write(client, handles, points[key("Term 16 (EL4732).Ch2 Sample 0")], samples)
    assert sim.get_symbol("Term 16 (EL4732).Ch2 Sample 0") == samples


@pytest.mark.e2e
async def test_an_online_change_fails_reads_and_writes_by_old_handles(
    sim: SimProcess, plan: SystemPlan, client: AdsClient
) -> None:
    """After the change the old handles read and write nothing: every item
    fails with 0x711 (nothing is handed on as a value) and a write raises;
    new handles work."""
    points = all_points(plan)
    recorder = Recorder()
    handles = await acquire(client, points)
    poller = Poller(
        client, points, handles.reads, recorder.on_changes, recorder.on_errors
    )
    await poller.poll_once()
    output = by_key(plan)[key("Term 15 (EL4134).AO Output Channel 2")]
    before = sim.get_symbol(output.symbol)
    sim.add_fault("online_change")
    recorder.changes.clear()
    await poller.poll_once()
    with pytest.raises(AdsHandleInvalidError):
        await write(client, handles, output, before + 1)
    fresh = await acquire(client, points)
    await write(client, fresh, output, before + 2)

    [errors] = recorder.errors
    assert recorder.changes == []
    assert {p.key for p, _ in errors} == {p.key for p in points}
    assert {code for _, code in errors} == {AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID}
    assert sim.get_symbol(output.symbol) == before + 2
    assert set(fresh.reads) == set(handles.reads)


@pytest.mark.e2e
async def test_a_symbol_whose_shape_changed_gets_no_read_handle(
    plan: SystemPlan, client: AdsClient
) -> None:
    """A handle is taken with the symbol's description: a symbol that is not
    what discovery saw (another size) is a problem, not a handle."""
    sample = by_key(plan)[key("Term 14 (EL3702).Ch1 Sample 0")]
    source = sample.source
    assert source is not None
    resized = replace(sample, source=replace(source, size=source.size + 2))
    moved = replace(source, name="Term 14 (EL3702).Ch9 Sample 0")
    gone = replace(sample, key="gone", source=moved)
    handles = await acquire(client, [resized, gone])

    assert handles.reads == {}
    assert "bytes) at discovery" in handles.problems[sample.source_name]
    assert handles.problems[gone.source_name] == "not in the symbol table any more"
    assert handles.read_problem(resized) == handles.problems[sample.source_name]


@pytest.mark.e2e
async def test_run_keeps_its_rate(plan: SystemPlan, client: AdsClient) -> None:
    recorder = Recorder()
    poller = await poller_of(client, all_points(plan), recorder)
    task = asyncio.create_task(poller.run(50.0))
    await asyncio.sleep(0.5)
    poller.stop()
    await asyncio.wait_for(task, 2)
    stats = poller.stats
    # 25 ticks in 0.5 s; ticks missed under load are skipped, not queued.
    assert 5 <= stats.cycles <= 27
    assert stats.cycles + stats.overruns <= 28
    assert stats.requests == stats.cycles
    mean_cycle_s = stats.total_cycle_s / stats.cycles
    assert mean_cycle_s > 0
    assert stats.max_cycle_s >= mean_cycle_s


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


def test_layout_reads_each_source_once_up_to_its_last_needed_byte() -> None:
    word_bits = [
        replace(
            synthetic(f"b{n}", 10, 2, PointKind.BIT, bit_offset=n, bit_size=1),
            source=Source("status"),
        )
        for n in (0, 9, 15)
    ]
    value = replace(synthetic("v", 12, 2), source=Source("status", 2))
    wc = [synthetic(f"wc{n}", 7, 1, PointKind.BIT) for n in range(2)]
    handles = {"status": 0x101, "wc0": 0x102, "wc1": 0x103}
    layout = PollLayout.build([*word_bits, value, *wc], handles)
    items = [
        (i.index_group, i.index_offset, i.length)
        for c in layout.chunks
        for i in c.items
    ]
    # A structure's bits and value: one item by its handle, 4 bytes; each
    # bit symbol its own one-byte item (0xF005: value by handle).
    assert items == [(0xF005, 0x101, 4), (0xF005, 0x102, 1), (0xF005, 0x103, 1)]


def test_decode_reports_only_changed_bits_and_values() -> None:
    bits = [
        synthetic(f"b{n}", 0, 2, PointKind.BIT, bit_offset=n, bit_size=1)
        for n in (1, 8, 15)
    ]
    field = synthetic("f", 0, 2, PointKind.BITS, bit_offset=6, bit_size=3)
    value = replace(synthetic("v", 2, 2), source=Source("w", 2))
    parts = [replace(p, source=Source("w")) for p in [*bits, field]]
    layout = PollLayout.build([*parts, value], {"w": 1})
    [chunk] = layout.chunks

    assert len(chunk.items) == 1

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
