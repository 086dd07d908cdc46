"""The IOC, wired: config -> target -> discovery -> PV names -> tree -> pollers.

    config = load_ioc_config(path, overrides)
    serve(config)           # until SIGINT/SIGTERM
    list_pvs(config)        # connect, discover, return every PV, no EPICS

Discovery runs on the loop that then serves, so the ADS clients (one worker
thread each) and FastCS share one event loop. One poll loop runs per master
and poll rate (the IOC's rate, or a terminal's own); each pushes only changed
values into the attributes. Warnings (shortened names, points without a PV,
aliases that matched nothing, discovery's own) go to stderr at start.
"""

from __future__ import annotations

import asyncio
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fastcs_ethercat.ads.client import AdsError
from fastcs_ethercat.ads.constants import AmsPort
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.attributes import CoeReader, CoeWriter
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.coe import SlaveCoe
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.controllers.master import MasterAds, MasterStatus
from fastcs_ethercat.ioc.controllers.root import PollStats
from fastcs_ethercat.ioc.controllers.tree import PvEntry, Tree, build_tree, slave_path
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.launch import LaunchOptions, run
from fastcs_ethercat.ioc.naming import alias_key
from fastcs_ethercat.ioc.plan import MasterPlan, Point, SystemPlan, TerminalPlan
from fastcs_ethercat.ioc.poller import Poller
from fastcs_ethercat.ioc.target import prepare_target
from fastcs_ethercat.terminals.loader import load_terminals


@dataclass
class PollGroup:
    """One poll loop: the points of one master polled at one rate."""

    master: MasterPlan
    rate_hz: float
    points: list[Point]
    poller: Poller | None = None


@dataclass
class Ioc:
    """Everything one running IOC holds."""

    config: IocConfig
    plan: SystemPlan
    tree: Tree
    pool: ClientPool
    groups: list[PollGroup] = field(default_factory=list)
    tasks: list[asyncio.Task[Any]] = field(default_factory=list)
    point_errors: dict[str, int] = field(default_factory=dict)
    rates: RateTracker = field(default_factory=lambda: RateTracker())

    async def stop(self) -> None:
        """Stop polling and close every ADS connection."""
        for task in self.tasks:
            task.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)
        await self.pool.close()

    def note_errors(self, errors: list[tuple[Point, int]]) -> None:
        """Points whose read failed this cycle (ADS return codes), for the record."""
        for point, code in errors:
            self.point_errors[point.key] = code

    def warnings(self) -> list[str]:
        """Everything a user should know about: nothing is dropped silently."""
        found = list(self.plan.warnings)
        for master in self.plan.masters:
            for terminal in master.terminals:
                found += [
                    w
                    if w.startswith(terminal.slave.name)
                    else f"{terminal.slave.name}: {w}"
                    for w in terminal.warnings
                ]
        found += [f"PV name shortened: {s}" for s in self.tree.names.shortened]
        found += [f"alias matches nothing: {k}" for k in self.tree.names.unused_aliases]
        found += [f"no PV for {src}: {why}" for src, why in self.tree.unserved()]
        return list(dict.fromkeys(found))


async def discover_system(config: IocConfig) -> tuple[SystemPlan, ClientPool]:
    """Prepare the target (NetId, route), connect and discover everything."""

    registry = load_terminals(config.terminal_dirs)
    net_id = await prepare_target(config)
    pool = ClientPool(config.target_host, config.target_port)
    try:
        plan = await discover(pool, registry, config, str(net_id))
    except AdsError as error:
        await pool.close()
        raise UserError(
            f"cannot discover the target: {error}", where="target"
        ) from None
    except BaseException:
        await pool.close()
        raise
    return plan, pool


def terminal_rate(
    config: IocConfig, master: MasterPlan, terminal: TerminalPlan
) -> float:
    """A terminal's poll rate: by its TwinCAT name or path, else the IOC's."""
    if terminal.poll_rate_hz is not None:
        return terminal.poll_rate_hz
    path = [node.name for node in slave_path(master, terminal)]
    return 1.0 / config.poll_period(terminal.slave.name, alias_key(path))


def poll_groups(config: IocConfig, plan: SystemPlan) -> list[PollGroup]:
    """The points of every master, grouped by poll rate (one loop each)."""
    groups: list[PollGroup] = []
    for master in plan.masters:
        by_rate: dict[float, list[Point]] = defaultdict(list)
        by_rate[config.poll_rate_hz] += master.master_points
        for terminal in master.terminals:
            by_rate[terminal_rate(config, master, terminal)] += terminal.points
        for rate, points in sorted(by_rate.items()):
            if points:
                groups.append(PollGroup(master, rate, points))
    return groups


def build_ioc(config: IocConfig, plan: SystemPlan, pool: ClientPool) -> Ioc:
    """The controller tree and its poll groups (pollers made when serving)."""
    groups = poll_groups(config, plan)
    group_of: dict[str, PollGroup] = {
        point.key: group for group in groups for point in group.points
    }

    async def write(point: Point, value: Any) -> None:
        group = group_of[point.key]
        if group.poller is None:
            raise RuntimeError("not polling yet")
        await group.poller.write_point(point, value)

    tree = build_tree(
        plan,
        config.prefix,
        target=config.target,
        writer=write,
        aliases=config.pv_aliases,
        coe_access=lambda master, terminal: _coe_access(pool, master, terminal),
        master_reader=lambda master: _master_reader(pool, master),
        read_only=config.read_only,
    )
    ioc = Ioc(config, plan, tree, pool, groups)
    tree.root.stats = lambda: _stats(ioc)
    return ioc


async def start_polling(ioc: Ioc) -> None:
    """One poller task per group; its changes go straight to the attributes.

    The poller hands on each cycle's changes synchronously; they are queued
    and posted in order by one task per group, so a slow cycle of posting
    never runs two batches at once.
    """

    for group in ioc.groups:
        client = await ioc.pool.get(ioc.plan.net_id, group.master.symbol_port)
        batches: asyncio.Queue[list[tuple[Point, Any]]] = asyncio.Queue()

        def on_changes(
            changes: list[tuple[Point, object]],
            _stamp: float,
            queue: asyncio.Queue[list[tuple[Point, Any]]] = batches,
        ) -> None:
            queue.put_nowait(changes)

        group.poller = Poller(client, group.points, on_changes, ioc.note_errors)
        ioc.tasks.append(asyncio.create_task(_post_batches(ioc, batches)))
        ioc.tasks.append(asyncio.create_task(group.poller.run(group.rate_hz)))


async def _post_batches(
    ioc: Ioc, batches: asyncio.Queue[list[tuple[Point, Any]]]
) -> None:
    sinks = ioc.tree.sinks
    while True:
        changes = await batches.get()
        for point, value in changes:
            sink = sinks.get(point.key)
            if sink is not None:
                await sink.apply_change(point, value)


def serve(
    config: IocConfig,
    *,
    on_ready: Callable[[], object] | None = None,
    on_built: Callable[[Ioc], object] | None = None,
) -> None:
    """Discover, build and serve until interrupted (this process's one IOC)."""
    loop = asyncio.new_event_loop()
    asyncio.set_event_loop(loop)
    plan, pool = loop.run_until_complete(discover_system(config))
    ioc = build_ioc(config, plan, pool)
    if on_built is not None:
        on_built(ioc)
    for warning in ioc.warnings():
        print(f"warning: {warning}", file=sys.stderr, flush=True)
    print(
        f"fastcs-ethercat: {len(plan.masters)} master(s),"
        f" {sum(len(m.terminals) for m in plan.masters)} terminals,"
        f" {ioc.tree.root.pv_count} PVs",
        flush=True,
    )

    def ready() -> None:
        ioc.tasks.append(loop.create_task(start_polling(ioc)))
        if on_ready is not None:
            on_ready()

    options = LaunchOptions(
        ca=config.transports.ca,
        pva=config.transports.pva,
        screens_dir=config.screens_dir,
        screens_title=f"EtherCAT {config.prefix}",
    )
    run(
        ioc.tree.root,
        config.prefix,
        options,
        on_ready=ready,
        loop=loop,
        on_stop=ioc.stop,
    )


def list_pvs(config: IocConfig) -> tuple[list[PvEntry], list[str]]:
    """Connect, discover and return every PV and every warning; serve nothing."""

    async def go() -> Ioc:
        plan, pool = await discover_system(config)
        try:
            return build_ioc(config, plan, pool)
        finally:
            await pool.close()

    ioc = asyncio.run(go())
    return ioc.tree.pvs(), ioc.warnings()


def _master_reader(pool: ClientPool, master: MasterPlan) -> Callable[[], Any] | None:
    addresses = [terminal.slave.address for terminal in master.terminals]

    readers: list[MasterAds] = []

    async def read() -> MasterStatus:
        if not readers:
            client = await pool.get(master.net_id, AmsPort.ETHERCAT_MASTER)
            readers.append(MasterAds(client, addresses))
        return await readers[0]()

    return read


def _coe_access(
    pool: ClientPool, master: MasterPlan, terminal: TerminalPlan
) -> tuple[CoeReader, CoeWriter] | None:
    if not terminal.coe:
        return None

    sdo = SlaveCoe(pool, master.net_id, terminal.slave.address)
    return sdo.read, sdo.write


@dataclass
class RateTracker:
    """Turns the pollers' running totals into per-second rates."""

    last_time: float = 0.0
    last_cycles: int = 0
    last_requests: int = 0
    cycles_per_second: float = 0.0
    requests_per_second: float = 0.0

    def update(self, now: float, cycles: int, requests: int) -> None:
        elapsed = now - self.last_time
        if self.last_time and elapsed > 0:
            self.cycles_per_second = (cycles - self.last_cycles) / elapsed
            self.requests_per_second = (requests - self.last_requests) / elapsed
        self.last_time, self.last_cycles, self.last_requests = now, cycles, requests


def _stats(ioc: Ioc) -> PollStats:
    pollers = [g.poller for g in ioc.groups if g.poller is not None]
    if not pollers:
        return PollStats()
    stats = [p.stats for p in pollers]
    ioc.rates.update(
        time.monotonic(),
        sum(s.cycles for s in stats),
        sum(s.requests for s in stats),
    )
    errors = [s.last_error for s in stats if s.last_error]
    return PollStats(
        connected=all(s.cycles > 0 for s in stats)
        and ioc.rates.requests_per_second > 0,
        cycle_time_ms=1000.0 * max(s.last_cycle_s for s in stats),
        poll_rate_hz=ioc.rates.cycles_per_second,
        requests_per_second=ioc.rates.requests_per_second,
        errors=sum(s.errors + s.item_errors for s in stats),
        last_error=errors[0] if errors else "",
    )
