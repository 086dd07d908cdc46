"""The root's reconnection component: what happens when the target goes and comes.

A `Supervisor` watches the target; this is the `Link` it drives. On a loss
polling stops and every target attribute goes INVALID (`health`); on return
the clients are reopened, the target discovered again, the chain compared
with the one the tree was built for and every point re-resolved by key (each
master's `use_plan`), so unchanged terminals keep their PVs and the process
never restarts. CoE values are read again after every resync.

A tree built from a chain file (the target did not answer at start) starts
disconnected: the supervisor reconnects first, and the first discovery is
compared with the chain it was built from like any other.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Collection, Sequence
from typing import Any, Final, Protocol

from fastcs.attributes import AttrR

from fastcs_ethercat.ads.constants import AdsState, AmsPort
from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.discovery import discover, read_symbol_version
from fastcs_ethercat.ioc.health import COMM, Health
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.ioc.supervisor import LinkState, Probe, Supervisor
from fastcs_ethercat.ioc.tasks import cancel_and_wait, gather_at_most
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry

logger = logging.getLogger(__name__)

COE_REFRESH_WAIT_S: Final = 10.0
"""How long CoE values wait after a resync for the link to count as up."""
COE_SLAVES_AT_ONCE: Final = 8
"""Slaves whose CoE values are read at the same time (one ADS client each)."""
CHAIN: Final = "chain"
"""Health reason: the point is gone from the target since a reconnect."""


class PolledMaster(Protocol):
    """A master controller, as far as polling goes."""

    async def start_polling(self) -> None: ...
    async def stop_polling(self) -> None: ...


class CoeTerminal(Protocol):
    """A terminal controller, as far as its CoE values go."""

    @property
    def coe_attributes(self) -> Sequence[AttrR[Any, Any]]: ...
    async def refresh_coe(self) -> None: ...


class ServedTree(Protocol):
    """What the reconnection acts on: the root controller's tree."""

    config: IocConfig
    health: Health

    @property
    def masters(self) -> Sequence[PolledMaster]: ...

    @property
    def plan(self) -> SystemPlan:
        """The plan the tree was built for."""
        ...

    def use_plan(
        self, plan: SystemPlan
    ) -> tuple[list[AttrR[Any, Any]], list[AttrR[Any, Any]]]: ...
    def target_attributes(self) -> list[AttrR[Any, Any]]: ...
    def terminals(self) -> Sequence[CoeTerminal]: ...
    async def show_link(self, state: str, error: str) -> None: ...


class Reconnection:
    """Polling, supervision and re-discovery of one root's target."""

    def __init__(
        self,
        root: ServedTree,
        connection: Connection,
        plan: SystemPlan,
        registry: TerminalRegistry | None = None,
    ) -> None:
        self.root = root
        self.connection = connection
        self.live = plan
        """The plan discovered last (after a reconnect); the root's built the tree."""
        self.registry = registry
        self.chain_changes = ""
        self.supervisor = Supervisor(
            self.probe,
            self,
            plan.symbol_version,
            connected=not plan.offline_from,
            heard_at=lambda: connection.pool.connection.stats.last_heard,
        )
        connection.state_of = lambda: self.supervisor.state
        connection.wake = self.supervisor.poke
        connection.resync = self.supervisor.request_resync
        self._tasks: list[asyncio.Task[Any]] = []
        self._coe_refresh: asyncio.Task[None] | None = None

    # -- life ----------------------------------------------------------------------

    def start(self) -> None:
        """Poll every master, watch the target, read every CoE value."""
        self._tasks.append(asyncio.create_task(self._start()))

    async def _start(self) -> None:
        if self.connection.connected:
            try:
                await self._start_polling()
            except Exception as error:  # e.g. no answer to the handles: resync
                reason = f"{type(error).__name__}: {error}"
                logger.warning("polling did not start: %s", reason)
                self.supervisor.request_resync(f"polling did not start ({reason})")
            self.start_coe_refresh()
        self._tasks.append(asyncio.create_task(self.supervisor.run()))

    async def stop(self) -> None:
        """Stop supervising and polling and close every ADS connection."""
        await self._stop_polling()
        tasks, self._tasks = self._tasks, []
        await cancel_and_wait(tasks)
        await self.connection.pool.close()

    async def _start_polling(self) -> None:
        for master in self.root.masters:
            await master.start_polling()

    async def _stop_polling(self) -> None:
        for master in self.root.masters:
            await master.stop_polling()

    # -- the supervisor's Link -------------------------------------------------------

    async def probe(self) -> Probe:
        """ADS state of the target's I/O server, symbol version of a master."""
        net_id = self.connection.net_id
        server = await self.connection.client(net_id, AmsPort.IO_SERVER)
        status = await server.read_state()
        version = -1
        masters = self.live.masters
        if masters and status.ads_state == AdsState.RUN:
            device = await self.connection.client(net_id, masters[0].symbol_port)
            version = await read_symbol_version(device)
        return Probe(int(status.ads_state), version)

    async def lost(self, reason: str) -> None:
        await self._invalidate(Status.COMM, reason)

    async def stopped(self, ads_state: int) -> None:
        await self._invalidate(Status.STATE, f"runtime not in RUN ({ads_state})")

    async def _invalidate(self, status: Status, reason: str) -> None:
        self._stop_coe_refresh()
        await self._stop_polling()
        root = self.root
        root.health.mark_invalid(root.target_attributes(), COMM, status, reason)
        await root.show_link(str(self.supervisor.state), reason)

    async def reconnect(self) -> int:
        """Fresh clients (AdsLib keeps dead routes), then discover and poll."""
        await self.connection.pool.close()
        server = await self.connection.client(self.connection.net_id, AmsPort.IO_SERVER)
        await server.read_state()
        origin = self.live.offline_from
        why = f"the live one against {origin}" if origin else "reconnected"
        return await self.resync(why)

    async def resync(self, why: str) -> int:
        """Discover again, compare the chain, re-resolve every point, poll."""
        root = self.root
        await self._stop_polling()
        if self.registry is None:
            self.registry = await asyncio.to_thread(
                load_terminals, root.config.terminal_dirs
            )
        plan = await discover(
            self.connection.client, self.registry, root.config, self.connection.net_id
        )
        found = chain_changes(root.plan, plan)
        self.live = plan
        gone, back = root.use_plan(plan)
        if gone:
            found.append(f"{len(gone)} served points gone or changed type")
            root.health.mark_invalid(
                gone, CHAIN, Status.STATE, "not on the target any more"
            )
        await root.health.mark_ok(back, CHAIN)
        changes = "; ".join(found)
        if changes != self.chain_changes:
            self.chain_changes = changes
            logger.warning(
                "chain (%s): %s", why, changes or "as at start again, all served"
            )
        await self._start_polling()
        await root.show_link(LinkState.CONNECTED, "")
        self.start_coe_refresh()
        return plan.symbol_version

    # -- CoE -------------------------------------------------------------------------

    def start_coe_refresh(self) -> None:
        self._stop_coe_refresh()
        task = asyncio.create_task(self._refresh_coe())
        self._coe_refresh = task
        self._tasks.append(task)  # cancelled by stop
        task.add_done_callback(self._forget_task)

    def _forget_task(self, task: asyncio.Task[Any]) -> None:
        if task in self._tasks:
            self._tasks.remove(task)

    def _stop_coe_refresh(self) -> None:
        if self._coe_refresh is not None:
            self._coe_refresh.cancel()
            self._coe_refresh = None

    async def _refresh_coe(self) -> None:
        """Read every CoE value from the slaves again: after an outage they
        may hold others (a power cycle resets them), and until read they
        stay INVALID. SDO access waits for the supervisor to say CONNECTED,
        which it does once `resync` has returned."""
        deadline = time.monotonic() + COE_REFRESH_WAIT_S
        while not self.connection.connected:
            if time.monotonic() > deadline:
                return
            await asyncio.sleep(0.02)
        # A slave's mailbox takes one SDO at a time; several slaves at once.
        terminals = [t for t in self.root.terminals() if t.coe_attributes]
        started = time.monotonic()
        await gather_at_most(COE_SLAVES_AT_ONCE, lambda t: t.refresh_coe(), terminals)
        if terminals:
            logger.info(
                "CoE values of %d terminals read in %.1f s",
                len(terminals),
                time.monotonic() - started,
            )


def chain_changes(old: SystemPlan, new: SystemPlan) -> list[str]:
    """What differs between two discoveries: masters, slaves, identities."""

    def slaves(plan: SystemPlan) -> dict[tuple[str, int], str]:
        return {
            (m.name, t.slave.address): f"{t.slave.name} {t.slave.identity}"
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
    added = _point_keys(new, before.keys()) - _point_keys(old, before.keys())
    if added:
        found.append(f"{len(added)} live points not served until restart")
    return found


def _point_keys(plan: SystemPlan, slaves: Collection[tuple[str, int]]) -> set[str]:
    """Keys of the points of `plan` on its masters and on `slaves`."""
    keys = {p.key for m in plan.masters for p in m.master_points}
    for master in plan.masters:
        for terminal in master.terminals:
            if (master.name, terminal.slave.address) in slaves:
                keys.update(p.key for p in terminal.points)
    return keys
