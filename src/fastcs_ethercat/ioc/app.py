"""The IOC, wired: config -> target -> discovery -> PV names -> tree -> pollers.

    config = load_ioc_config(path, overrides)
    serve(config)           # until SIGINT/SIGTERM
    list_pvs(config)        # connect, discover, return every PV, no EPICS

Discovery runs on the loop that then serves, so the ADS clients (one worker
thread each) and FastCS share one event loop. One poll loop runs per master
and poll rate (the IOC's rate, or a terminal's own); each pushes only changed
values into the attributes. Warnings (shortened names, points without a PV,
aliases that matched nothing, discovery's own) go to stderr at start.

Once serving, a `Supervisor` watches the target (`TargetLink` is what it
drives): on a loss polling stops and every target attribute goes INVALID
(`health`); on return the clients are reopened, the target discovered again,
the chain compared with the one the tree was built for and every point
re-resolved by key, so unchanged terminals keep their PVs and the process
never restarts. Writes are checked, sent once or refused, never queued.
"""

from __future__ import annotations

import asyncio
import logging
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Final

from fastcs_ethercat.ads.client import AdsError, unreachable
from fastcs_ethercat.ads.constants import AdsState, AmsPort, describe_return_code
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.attributes import CoeReader, CoeWriter
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.coe import SlaveCoe
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.controllers.master import MasterAds, MasterStatus
from fastcs_ethercat.ioc.controllers.root import PollStats
from fastcs_ethercat.ioc.controllers.terminal import COE_READ, TerminalController
from fastcs_ethercat.ioc.controllers.tree import PvEntry, Tree, build_tree, slave_path
from fastcs_ethercat.ioc.discovery import discover, read_symbol_version
from fastcs_ethercat.ioc.health import COMM, READ
from fastcs_ethercat.ioc.launch import LaunchOptions, run
from fastcs_ethercat.ioc.naming import alias_key
from fastcs_ethercat.ioc.plan import (
    CoePoint,
    MasterPlan,
    Point,
    SystemPlan,
    TerminalPlan,
)
from fastcs_ethercat.ioc.poller import Poller, write_point
from fastcs_ethercat.ioc.supervisor import LinkState, Probe, Supervisor
from fastcs_ethercat.ioc.target import prepare_target
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry

logger = logging.getLogger(__name__)

COE_REFRESH_WAIT_S: Final = 10.0
COE_SLAVES_AT_ONCE: Final = 8
"""Slaves whose CoE values are read at the same time (one ADS client each)."""
"""How long CoE values wait after a resync for the link to count as up."""
CHAIN: Final = "chain"
"""Health reason: the point is gone from the target since a reconnect."""


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
    registry: TerminalRegistry | None = None
    live: SystemPlan | None = None
    """The plan discovered last (after a reconnect); `plan` built the tree."""
    points: dict[str, Point] = field(default_factory=dict)
    """Point key -> the point as the target has it now (offsets move)."""
    group_of: dict[str, PollGroup] = field(default_factory=dict)
    poll_tasks: list[asyncio.Task[Any]] = field(default_factory=list)
    supervisor: Supervisor | None = None
    chain_changes: str = ""
    writes: int = 0
    write_errors: int = 0

    @property
    def connected(self) -> bool:
        return self.supervisor is None or self.supervisor.state is LinkState.CONNECTED

    async def stop(self) -> None:
        """Stop supervising and polling and close every ADS connection."""
        await stop_polling(self)
        for task in self.tasks:
            task.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)
        await self.pool.close()

    def note_errors(self, errors: list[tuple[Point, int]]) -> None:
        """Points whose read failed this cycle: only they go into alarm."""
        by_code: dict[int, list[Any]] = defaultdict(list)
        for point, code in errors:
            self.point_errors[point.key] = code
            attr = self.tree.attribute(point.key)
            if attr is not None:
                by_code[code].append(attr)
        for code, attrs in by_code.items():
            if unreachable(code):  # no answer: the target, not the point
                reason, status = COMM, Status.COMM
            else:
                reason, status = READ, Status.READ
            self.tree.health.mark_invalid(
                attrs, reason, status, describe_return_code(code)
            )
        if self.supervisor is not None and len(errors) >= len(self.points):
            self.supervisor.poke()  # the whole read failed: is the target there?

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


async def discover_system(
    config: IocConfig, registry: TerminalRegistry | None = None
) -> tuple[SystemPlan, ClientPool]:
    """Prepare the target (NetId, route), connect and discover everything."""

    if registry is None:
        registry = load_terminals(config.terminal_dirs)
    net_id = await prepare_target(config)
    pool = ClientPool(config.target_host, config.target_port, config.ads_timeout_ms)
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


def poll_groups(
    config: IocConfig, plan: SystemPlan, keep: Callable[[Point], bool] | None = None
) -> list[PollGroup]:
    """The points of every master, grouped by poll rate (one loop each)."""
    groups: list[PollGroup] = []
    for master in plan.masters:
        by_rate: dict[float, list[Point]] = defaultdict(list)
        by_rate[config.poll_rate_hz] += master.master_points
        for terminal in master.terminals:
            by_rate[terminal_rate(config, master, terminal)] += terminal.points
        for rate, points in sorted(by_rate.items()):
            points = [p for p in points if keep is None or keep(p)]
            if points:
                groups.append(PollGroup(master, rate, points))
    return groups


def build_ioc(
    config: IocConfig,
    plan: SystemPlan,
    pool: ClientPool,
    registry: TerminalRegistry | None = None,
) -> Ioc:
    """The controller tree and its poll groups (pollers made when serving)."""
    holder: list[Ioc] = []

    async def write(point: Point, value: Any) -> None:
        await _write(holder[0], point, value)

    def connected() -> bool:
        return bool(holder) and holder[0].connected

    tree = build_tree(
        plan,
        config.prefix,
        target=config.target,
        writer=write,
        aliases=config.pv_aliases,
        coe_access=lambda master, terminal: _coe_access(
            pool, master, terminal, connected, config.read_only
        ),
        master_reader=lambda master: _master_reader(pool, master, connected),
        read_only=config.read_only,
    )
    ioc = Ioc(config, plan, tree, pool, registry=registry)
    holder.append(ioc)
    _use_plan(ioc, plan)
    tree.root.stats = lambda: _stats(ioc)
    return ioc


def _use_plan(ioc: Ioc, plan: SystemPlan) -> None:
    """Poll the points of `plan` that the tree serves (after any discovery)."""
    served = {key for key in ioc.tree.sinks if ioc.tree.attribute(key) is not None}
    built = {p.key: p for p in _all_points(ioc.plan)}

    def keep(point: Point) -> bool:
        old = built.get(point.key)
        return point.key in served and old is not None and _same_shape(old, point)

    ioc.live = plan
    ioc.groups = poll_groups(ioc.config, plan, keep)
    ioc.group_of = {p.key: g for g in ioc.groups for p in g.points}
    ioc.points = {p.key: p for g in ioc.groups for p in g.points}


def _all_points(plan: SystemPlan) -> list[Point]:
    points: list[Point] = []
    for master in plan.masters:
        points += master.master_points
        for terminal in master.terminals:
            points += terminal.points
    return points


def _same_shape(old: Point, new: Point) -> bool:
    """The attribute made for `old` can serve `new` (same type, same form)."""
    return (
        old.type_name == new.type_name
        and old.kind is new.kind
        and old.length == new.length
        and old.bit_size == new.bit_size
        and old.writable == new.writable
    )


async def _write(ioc: Ioc, point: Point, value: Any) -> None:
    """One write from a client: checked, never queued, never repeated.

    Rejected while the IOC is read-only or the target is not connected; the
    live point (offsets as the target has them now) is checked and written
    once. An ADS error puts the PV into WRITE alarm, is logged and raised.
    """
    if ioc.config.read_only:
        raise PermissionError("read-only IOC: no ADS writes")
    if not ioc.connected:
        raise ConnectionError(f"target not connected: write to {point.symbol} refused")
    live = ioc.points.get(point.key)
    group = ioc.group_of.get(point.key)
    if live is None or group is None:
        raise LookupError(f"{point.symbol} is not on the target any more")
    client = await ioc.pool.get(ioc.plan.net_id, group.master.symbol_port)
    try:
        await write_point(client, live, value)
    except AdsError as error:
        ioc.write_errors += 1
        logger.error("write of %r to %s failed: %s", value, point.symbol, error)
        attr = ioc.tree.attribute(point.key)
        if attr is not None:
            ioc.tree.health.write_failed(attr, str(error))
        raise
    ioc.writes += 1
    if group.poller is not None:
        group.poller.invalidate()  # the readback shows what the PLC holds


async def start_polling(ioc: Ioc) -> None:
    """One poller task per group; its changes go straight to the attributes.

    The poller hands on each cycle's changes synchronously, with the time of
    its read; they are queued and posted in order by one task per group, so
    a slow cycle of posting never runs two batches at once, and every value
    of one cycle is published with that cycle's one timestamp.
    """
    ioc.tree.health.publisher.start()
    for group in ioc.groups:
        client = await ioc.pool.get(ioc.plan.net_id, group.master.symbol_port)
        batches: asyncio.Queue[Batch] = asyncio.Queue()

        def on_changes(
            changes: list[tuple[Point, object]],
            stamp: float,
            queue: asyncio.Queue[Batch] = batches,
        ) -> None:
            queue.put_nowait((changes, stamp))

        group.poller = Poller(client, group.points, on_changes, ioc.note_errors)
        ioc.poll_tasks.append(asyncio.create_task(_post_batches(ioc, batches)))
        ioc.poll_tasks.append(asyncio.create_task(group.poller.run(group.rate_hz)))


async def stop_polling(ioc: Ioc) -> None:
    """Stop every poller and its posting task (before the clients go)."""
    for group in ioc.groups:
        if group.poller is not None:
            group.poller.stop()
    tasks, ioc.poll_tasks = ioc.poll_tasks, []
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)


Batch = tuple[list[tuple[Point, Any]], float]
"""One poll cycle's changes and the time of its read."""


async def _post_batches(ioc: Ioc, batches: asyncio.Queue[Batch]) -> None:
    sinks = ioc.tree.sinks
    while True:
        changes, stamp = await batches.get()
        for point, value in changes:
            sink = sinks.get(point.key)
            if sink is not None:
                await sink.apply_change(point, value, stamp)


class TargetLink:
    """What the supervisor does to the IOC when the target goes and comes."""

    def __init__(self, ioc: Ioc) -> None:
        self.ioc = ioc
        self.coe_refresh: asyncio.Task[None] | None = None
        """Reading the CoE values again after a resync (one at a time)."""

    async def probe(self) -> Probe:
        """ADS state of the target's I/O server, symbol version of a master."""
        ioc = self.ioc
        server = await ioc.pool.get(ioc.plan.net_id, AmsPort.IO_SERVER)
        status = await server.read_state()
        version = -1
        masters = (ioc.live or ioc.plan).masters
        if masters and status.ads_state == AdsState.RUN:
            device = await ioc.pool.get(ioc.plan.net_id, masters[0].symbol_port)
            version = await read_symbol_version(device)
        return Probe(int(status.ads_state), version)

    async def lost(self, reason: str) -> None:
        await self._invalidate(Status.COMM, reason)

    async def stopped(self, ads_state: int) -> None:
        await self._invalidate(Status.STATE, f"runtime not in RUN ({ads_state})")

    async def _invalidate(self, status: Status, reason: str) -> None:
        ioc = self.ioc
        self._stop_coe_refresh()
        await stop_polling(ioc)
        ioc.tree.health.mark_invalid(ioc.tree.target_attributes(), COMM, status, reason)
        await ioc.tree.root.show_link(_state(ioc), reason)

    async def reconnect(self) -> int:
        """Fresh clients (AdsLib keeps dead routes), then discover and poll."""
        ioc = self.ioc
        await ioc.pool.close()
        server = await ioc.pool.get(ioc.plan.net_id, AmsPort.IO_SERVER)
        await server.read_state()
        return await self.resync("reconnected")

    async def resync(self, why: str) -> int:
        """Discover again, compare the chain, re-resolve every point, poll."""
        ioc = self.ioc
        await stop_polling(ioc)
        if ioc.registry is None:
            ioc.registry = await asyncio.to_thread(
                load_terminals, ioc.config.terminal_dirs
            )
        plan = await discover(ioc.pool, ioc.registry, ioc.config, ioc.plan.net_id)
        found = chain_changes(ioc.plan, plan)
        _use_plan(ioc, plan)
        gone = [
            attr
            for key in ioc.tree.sinks
            if key not in ioc.points and (attr := ioc.tree.attribute(key)) is not None
        ]
        if gone:
            found.append(f"{len(gone)} served points gone or changed type")
        changes = "; ".join(found)
        if gone:
            ioc.tree.health.mark_invalid(
                gone, CHAIN, Status.STATE, "not on the target any more"
            )
        back = [
            attr for key in ioc.points if (attr := ioc.tree.attribute(key)) is not None
        ]
        await ioc.tree.health.mark_ok(back, CHAIN)
        if changes != ioc.chain_changes:
            ioc.chain_changes = changes
            logger.warning(
                "chain (%s): %s", why, changes or "as at start again, all served"
            )
        _follow_positions(ioc, plan)
        await start_polling(ioc)
        await ioc.tree.root.show_link(LinkState.CONNECTED, "")
        self.start_coe_refresh()
        return plan.symbol_version

    def start_coe_refresh(self) -> None:
        self._stop_coe_refresh()
        task = asyncio.create_task(self._refresh_coe())
        self.coe_refresh = task
        self.ioc.tasks.append(task)  # cancelled by Ioc.stop
        task.add_done_callback(self._forget_task)

    def _forget_task(self, task: asyncio.Task[None]) -> None:
        if task in self.ioc.tasks:
            self.ioc.tasks.remove(task)

    def _stop_coe_refresh(self) -> None:
        if self.coe_refresh is not None:
            self.coe_refresh.cancel()
            self.coe_refresh = None

    async def _refresh_coe(self) -> None:
        """Read every CoE value from the slaves again: after an outage they
        may hold others (a power cycle resets them), and until read they
        stay INVALID. SDO access waits for the supervisor to say CONNECTED,
        which it does once `resync` has returned."""
        ioc = self.ioc
        deadline = time.monotonic() + COE_REFRESH_WAIT_S
        while not ioc.connected:
            if time.monotonic() > deadline:
                return
            await asyncio.sleep(0.02)
        # A slave's mailbox takes one SDO at a time; several slaves at once.
        slots = asyncio.Semaphore(COE_SLAVES_AT_ONCE)

        async def refresh(terminal: TerminalController) -> None:
            async with slots:
                await terminal.refresh_coe()

        await asyncio.gather(
            *(refresh(t) for t in ioc.tree.terminals() if t.coe_attributes)
        )


def chain_changes(old: SystemPlan, new: SystemPlan) -> list[str]:
    """What differs between two discoveries: masters, slaves, identities."""

    def slaves(plan: SystemPlan) -> dict[tuple[str, int], str]:
        return {
            (m.name, t.slave.address): (
                f"{t.slave.name} 0x{t.slave.vendor_id:X}/"
                f"0x{t.slave.product_code:X}/0x{t.slave.revision:X}"
            )
            for m in plan.masters
            for t in m.terminals
        }

    before, after = slaves(old), slaves(new)
    found: list[str] = []
    for key in sorted(before.keys() | after.keys()):
        was, now = before.get(key), after.get(key)
        if was == now:
            continue
        where = f"{key[0]} slave {key[1]}"
        if now is None:
            found.append(f"{where} gone ({was})")
        elif was is None:
            found.append(f"{where} new ({now}, not served until restart)")
        else:
            found.append(f"{where} {was} -> {now}")
    return found


def _follow_positions(ioc: Ioc, plan: SystemPlan) -> None:
    """Masters read slave states by bus position: use the positions found now."""
    by_name = {m.name: m for m in plan.masters}
    for controller in ioc.tree.masters:
        master = by_name.get(controller.plan.name)
        if master is None:
            continue
        for terminal in master.terminals:
            if terminal.slave.address in controller.terminal_positions:
                controller.terminal_positions[terminal.slave.address] = (
                    terminal.slave.position
                )


def _state(ioc: Ioc) -> str:
    return str(ioc.supervisor.state) if ioc.supervisor is not None else "CONNECTED"


async def start_supervising(ioc: Ioc) -> Supervisor:
    """Poll, and watch the target from now on."""
    link = TargetLink(ioc)
    if ioc.registry is None:  # for discoveries after a reconnect
        ioc.registry = await asyncio.to_thread(load_terminals, ioc.config.terminal_dirs)
    supervisor = Supervisor(link.probe, link, ioc.plan.symbol_version)
    ioc.supervisor = supervisor
    await start_polling(ioc)
    ioc.tasks.append(asyncio.create_task(supervisor.run()))
    # CoE values are read now that every PV serves, not before: thousands of
    # SDO uploads (mailbox round trips on a real bus) would hold up the start.
    # Until read, each is INVALID (UDF).
    coe = [a for t in ioc.tree.terminals() for a in t.coe_attributes]
    ioc.tree.health.mark_invalid(coe, COE_READ, Status.UDF, "not read yet")
    link.start_coe_refresh()
    return supervisor


def serve(
    config: IocConfig,
    *,
    on_ready: Callable[[], object] | None = None,
    on_built: Callable[[Ioc], object] | None = None,
) -> None:
    """Discover, build and serve until interrupted (this process's one IOC)."""
    loop = asyncio.new_event_loop()
    asyncio.set_event_loop(loop)
    registry = load_terminals(config.terminal_dirs)
    plan, pool = loop.run_until_complete(discover_system(config, registry))
    ioc = build_ioc(config, plan, pool, registry)  # kept for re-discoveries
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
        ioc.tasks.append(loop.create_task(start_supervising(ioc)))
        if on_ready is not None:
            on_ready()

    options = LaunchOptions(
        ca=config.transports.ca,
        pva=config.transports.pva,
        screens_dir=config.screens_dir,
        screens_title=f"EtherCAT {config.prefix}",
        access_security_file=config.access_security_file,
        read_only=config.read_only,
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

    async def go() -> tuple[list[PvEntry], list[str]]:
        # Return plain lists, not the Ioc: asyncio.run formats its main task's
        # result on the way out, and the repr of a large Ioc takes minutes.
        plan, pool = await discover_system(config)
        try:
            ioc = build_ioc(config, plan, pool)
            return ioc.tree.pvs(), ioc.warnings()
        finally:
            await pool.close()

    return asyncio.run(go())


def _master_reader(
    pool: ClientPool, master: MasterPlan, connected: Callable[[], bool]
) -> Callable[[], Any] | None:
    """The master's diagnostics, through the pool's client of the moment."""
    reader = MasterAds(None, [terminal.slave.address for terminal in master.terminals])

    async def read() -> MasterStatus:
        if not connected():
            raise ConnectionError("target not connected")
        reader.client = await pool.get(master.net_id, AmsPort.ETHERCAT_MASTER)
        return await reader()

    return read


def _coe_access(
    pool: ClientPool,
    master: MasterPlan,
    terminal: TerminalPlan,
    connected: Callable[[], bool],
    read_only: bool,
) -> tuple[CoeReader, CoeWriter] | None:
    """SDO access of one slave; refused while the target is away (or read-only)."""
    if not terminal.coe:
        return None

    sdo = SlaveCoe(pool, master.net_id, terminal.slave.address)

    async def read(coe: CoePoint) -> Any:
        if not connected():
            raise ConnectionError("target not connected")
        return await sdo.read(coe)

    async def write(coe: CoePoint, value: Any) -> None:
        if read_only:
            raise PermissionError("read-only IOC: no ADS writes")
        if not connected():
            raise ConnectionError("target not connected: SDO write refused")
        await sdo.write(coe, value)

    return read, write


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
        restarted = cycles < self.last_cycles or requests < self.last_requests
        if self.last_time and elapsed > 0 and not restarted:  # new pollers: skip
            self.cycles_per_second = (cycles - self.last_cycles) / elapsed
            self.requests_per_second = (requests - self.last_requests) / elapsed
        self.last_time, self.last_cycles, self.last_requests = now, cycles, requests


def _stats(ioc: Ioc) -> PollStats:
    pollers = [g.poller for g in ioc.groups if g.poller is not None]
    stats = [p.stats for p in pollers]
    ioc.rates.update(
        time.monotonic(),
        sum(s.cycles for s in stats),
        sum(s.requests for s in stats),
    )
    supervisor = ioc.supervisor
    link = supervisor.stats if supervisor is not None else None
    errors = [s.last_error for s in stats if s.last_error]
    last_error = errors[0] if errors else ""
    if link is not None and (not ioc.connected or not last_error):
        last_error = link.last_error
    return PollStats(
        connected=ioc.connected and bool(stats) and all(s.cycles > 0 for s in stats),
        cycle_time_ms=1000.0 * max((s.last_cycle_s for s in stats), default=0.0),
        poll_rate_hz=ioc.rates.cycles_per_second,
        requests_per_second=ioc.rates.requests_per_second,
        errors=sum(s.errors + s.item_errors for s in stats),
        last_error=last_error,
        state=_state(ioc),
        reconnects=(link.reconnects + link.resyncs) if link is not None else 0,
        last_recovery_s=link.last_recovery_s if link is not None else 0.0,
        chain_changes=ioc.chain_changes,
        invalid=ioc.tree.health.invalid_count,
        symbol_version=(ioc.live or ioc.plan).symbol_version,
    )
