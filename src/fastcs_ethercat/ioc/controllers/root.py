"""The root controller: start-up (discovery, the tree), the link, statistics.

FastCS calls `initialise()` before it builds the transports: the root finds
its plan there (`PlanSource`, `ioc.boot`: the live target, or a configured or
cached chain while the PLC does not answer), names every PV at once and
builds one `MasterController` per master below it. Every plan discovered on
the live target (at start and after every resync) is kept as this target's
chain (`ioc.chains`), for the next start without the PLC. Once the
transports serve, `start()` hands over to the `Reconnection` component
(pollers, supervisor, CoE reads); a tree built from a chain starts with
every target PV INVALID/COMM and the supervisor looking for the target.
FastCS's `disconnect()` stops it all. Statistics come from the masters'
pollers and the supervisor, read once a second; nothing here raises out of
its scan.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import Any, Final, NamedTuple

from fastcs.attributes import AttrR
from fastcs.controllers import Controller
from fastcs.datatypes import Int, String
from fastcs.methods import scan

from fastcs_ethercat import __version__, collector
from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.boot import PlanSource
from fastcs_ethercat.ioc.chains import remember
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.controllers.master import MasterController
from fastcs_ethercat.ioc.controllers.terminal import COE_READ, TerminalController
from fastcs_ethercat.ioc.controllers.tree import (
    PvEntry,
    build_masters,
    pv_count,
    pv_entries,
    pv_requests,
    requests_by_terminal,
    slave_path,
)
from fastcs_ethercat.ioc.datatypes import AlarmBool, ExactFloat, alarm_enum
from fastcs_ethercat.ioc.deadband import Deadbands
from fastcs_ethercat.ioc.health import COMM, Health
from fastcs_ethercat.ioc.heartbeat import Heartbeat, count_start
from fastcs_ethercat.ioc.naming import (
    MAX_PV_LENGTH,
    PvNames,
    PvRequest,
    alias_key,
    plan_pv_names,
)
from fastcs_ethercat.ioc.plan import MasterPlan, SystemPlan, TerminalPlan
from fastcs_ethercat.ioc.process_stats import DEVIOCSTATS_NAMES, ProcessStats
from fastcs_ethercat.ioc.publish import Publisher
from fastcs_ethercat.ioc.reconnect import Reconnection
from fastcs_ethercat.ioc.supervisor import LinkState
from fastcs_ethercat.logs import first_names, log_at_most
from fastcs_ethercat.terminals.registry import TerminalRegistry

logger = logging.getLogger(__name__)

STATS_PERIOD_S: Final = 1.0
PREPARED_AT_ONCE: Final = 200
"""Routes made between two looks at whether EPICS still sleeps (~10 ms)."""
WARNINGS_SHOWN: Final = 15
"""Start-up warnings logged before one line says how many more there are."""
PROCESS_LEAVES: Final = (
    "Version",
    "StartTime",
    "Uptime",
    "CpuLoad",
    "MemoryUsed",
    "PollOverruns",
    *DEVIOCSTATS_NAMES,
)
"""The IOC process's health (what devIocStats gives a C IOC; the last ones
with devIocStats' meaning, served on CA under its names too)."""
LINK_SEVERITIES: Final = {
    LinkState.CONNECTED: 0,
    LinkState.RESYNCING: 1,
    LinkState.DISCONNECTED: 2,
    LinkState.STOPPED: 2,
}
"""`ConnectionState` as an alarm: a resync is MINOR, no target MAJOR."""
ROOT_LEAVES: Final = (
    "Connected",
    "Target",
    "NetId",
    "DeviceName",
    "DeviceVersion",
    "SymbolVersion",
    "Masters",
    "Terminals",
    "PvCount",
    "Unserved",
    "PollCycleTime",
    "PollRate",
    "AdsRequestRate",
    "PostRate",
    "PollErrors",
    "LastError",
    "ConnectionState",
    "Reconnects",
    "Resyncs",
    "LastRecovery",
    "ChainChanges",
    "InvalidPvs",
    *PROCESS_LEAVES,
)


class Totals(NamedTuple):
    """The pollers' poll cycles and ADS requests and the publisher's posts
    so far, at one moment (time.monotonic())."""

    time: float
    cycles: int
    requests: int
    posts: int


@dataclass
class RateTracker:
    """Turns the running totals into per-second rates."""

    last: Totals | None = None
    cycles_per_second: float = 0.0
    requests_per_second: float = 0.0
    posts_per_second: float = 0.0

    def update(self, now: Totals) -> None:
        last, self.last = self.last, now
        if last is None or now.time <= last.time:
            return
        elapsed = now.time - last.time
        restarted = now.cycles < last.cycles or now.requests < last.requests
        if not restarted:  # new pollers (a reconnect): skip
            self.cycles_per_second = (now.cycles - last.cycles) / elapsed
            self.requests_per_second = (now.requests - last.requests) / elapsed
        self.posts_per_second = (now.posts - last.posts) / elapsed


class RootController(Controller):
    """`<prefix>`: the target, its masters below, and how the IOC is doing."""

    def __init__(
        self,
        config: IocConfig,
        plan_source: PlanSource,
        registry: TerminalRegistry | None = None,
    ) -> None:
        super().__init__(description=f"EtherCAT on {config.target}")
        self.set_path([config.prefix])
        self.config = config
        self.plan_source = plan_source
        self.registry = registry
        """The terminal YAML, kept for discoveries after a reconnect."""
        self.health = Health(Publisher(Deadbands.of_config(config.deadbands)))
        self.masters: list[MasterController] = []
        self.attrs: dict[str, AttrR[Any, Any]] = {}
        self.pv_count = 0
        self.unserved = 0
        self.rates = RateTracker()
        self.process = ProcessStats()
        self.heartbeat: Heartbeat | None = None
        """Made when the IOC starts to serve, before it looks for its chain
        (not for `--list-pvs`)."""
        self.start_count = 0
        self._plan: SystemPlan | None = None
        self._names: PvNames | None = None
        self._reconnection: Reconnection | None = None

    @property
    def plan(self) -> SystemPlan:
        """The plan the tree was built for."""
        assert self._plan is not None, "not initialised"
        return self._plan

    @property
    def names(self) -> PvNames:
        assert self._names is not None, "not initialised"
        return self._names

    @property
    def reconnection(self) -> Reconnection:
        assert self._reconnection is not None, "not initialised"
        return self._reconnection

    # -- start-up ------------------------------------------------------------------

    async def initialise(self) -> None:
        """Find the plan and build the tree (FastCS calls this before serving)."""
        if self._plan is not None:
            return
        self.heartbeat = Heartbeat()  # alive while it waits for the PLC
        self.heartbeat.keep_fresh()
        try:
            plan, connection = await self.plan_source()
        except BaseException:
            self.heartbeat.stop_keeping_fresh()
            raise
        started = time.monotonic()
        collector.pause()  # a burst of objects that live on, until `start`
        self.build(plan, connection)
        logger.info(
            "%d PVs planned in %.1f s; creating their records",
            self.pv_count,
            time.monotonic() - started,
        )
        log_at_most(
            logger,
            logging.WARNING,
            fold_by_terminal(self.warnings(), self._slave_names()),
            WARNINGS_SHOWN,
            "warnings (every one: `ioc --list-pvs`, or at debug level)",
        )

    def _slave_names(self) -> set[str]:
        return {t.slave.name for m in self.plan.masters for t in m.terminals}

    def build(self, plan: SystemPlan, connection: Connection) -> None:
        """The attributes of the root and every controller below, for `plan`."""
        config = self.config
        self._plan = plan
        by_terminal = requests_by_terminal(plan)
        self._names = names = plan_pv_names(
            config.prefix,
            pv_requests(plan, ROOT_LEAVES, by_terminal),
            config.pv_aliases,
        )
        for shortening in names.shortened:  # thousands with every CoE object
            logger.debug("PV name shortened: %s", shortening)
        self.attrs = _root_attributes(plan, config.target, self.process)
        for leaf, attr in self.attrs.items():
            self.add_attribute(names.leaves[PvRequest((), leaf)], attr)
        self.masters = build_masters(
            self,
            plan,
            names,
            connection,
            self.health,
            read_only=config.read_only,
            by_terminal=by_terminal,
        )
        self._reconnection = Reconnection(self, connection, plan, self.registry)
        self._poll(plan)
        self.pv_count = pv_count(self)
        self.unserved = len(self.unserved_points())

    def use_plan(
        self, plan: SystemPlan
    ) -> tuple[list[AttrR[Any, Any]], list[AttrR[Any, Any]]]:
        """Every master polls what `plan` (a discovery) has of its points;
        (attributes gone from the target, attributes served)."""
        self.keep_chain(plan)
        return self._poll(plan)

    def keep_chain(self, plan: SystemPlan) -> None:
        """`plan`'s chain, if discovered live, becomes the one an offline start
        serves (`ioc.chains`). The start keeps it once every PV exists, while
        EPICS sleeps (`prepare`): not in the way of the records."""
        if not plan.offline_from:
            remember(plan, self.config.target)

    def _poll(
        self, plan: SystemPlan
    ) -> tuple[list[AttrR[Any, Any]], list[AttrR[Any, Any]]]:
        by_name = {m.name: m for m in plan.masters}
        gone: list[AttrR[Any, Any]] = []
        served: list[AttrR[Any, Any]] = []
        for controller in self.masters:
            live = by_name.get(controller.plan.name) or MasterPlan(
                controller.plan.device_id, controller.plan.name, "", 0
            )
            lost, kept = controller.use_plan(live, self._rate_of(live))
            gone += lost
            served += kept
        return gone, served

    def _rate_of(self, master: MasterPlan) -> Callable[[TerminalPlan | None], float]:
        """A terminal's poll rate: by its TwinCAT name or path, else the IOC's."""
        config = self.config

        def rate(terminal: TerminalPlan | None) -> float:
            if terminal is None:
                return config.poll_rate_hz
            if terminal.poll_rate_hz is not None:
                return terminal.poll_rate_hz
            path = [node.name for node in slave_path(master, terminal)]
            return 1.0 / config.poll_period(terminal.slave.name, alias_key(path))

        return rate

    # -- what it serves ------------------------------------------------------------

    def terminals(self) -> list[TerminalController]:
        """Every terminal controller, master by master, in bus order."""
        return [t for master in self.masters for t in master.terminals.values()]

    def target_attributes(self) -> list[AttrR[Any, Any]]:
        """Every attribute whose value comes from the target (not the IOC)."""
        return [a for master in self.masters for a in master.target_attributes()]

    def own_attributes(self) -> list[AttrR[Any, Any]]:
        """Every attribute whose value the IOC sets itself (statistics,
        diagnostics, identities): neither read from the target's process
        image nor a CoE object."""
        elsewhere = {id(a) for a in self.target_attributes()}
        elsewhere.update(id(a) for t in self.terminals() for a in t.coe_attributes)
        found: list[AttrR[Any, Any]] = []
        controllers: list[Any] = [self]
        while controllers:
            controller = controllers.pop()
            controllers.extend(controller.sub_controllers.values())
            found += [
                a
                for a in controller.attributes.values()
                if isinstance(a, AttrR) and id(a) not in elsewhere
            ]
        return found

    def pvs(self) -> list[PvEntry]:
        """Every PV the tree serves (CA names), sorted by name."""
        return pv_entries(self)

    def unserved_points(self) -> list[tuple[str, str]]:
        """(source, reason) of every point that got no PV."""
        found: list[tuple[str, str]] = []
        for master in self.masters:
            found += master.unserved
            for terminal in master.terminals.values():
                found += terminal.unserved
        return found

    def warnings(self) -> list[str]:
        """Everything a user should know about: nothing is dropped silently
        (shortened names in one line, each at debug level)."""
        plan = self.plan
        found = list(plan.warnings)
        for master in plan.masters:
            for terminal in master.terminals:
                found += [
                    w
                    if w.startswith(terminal.slave.name)
                    else f"{terminal.slave.name}: {w}"
                    for w in terminal.warnings
                ]
        if shortened := self.names.shortened:
            hashed = sum(shortening.hashed for shortening in shortened)
            found.append(
                f"{len(shortened)} PV name segments shortened to fit"
                f" {MAX_PV_LENGTH} characters ({hashed} cut and given a hash);"
                " each is logged at debug level"
            )
        found += [f"alias matches nothing: {k}" for k in self.names.unused_aliases]
        found += [f"no PV for {src}: {why}" for src, why in self.unserved_points()]
        return list(dict.fromkeys(found))

    # -- serving -------------------------------------------------------------------

    async def prepare(self) -> None:
        """The database serves (iocInit has returned): where each value from
        the target will go is worked out now, not at its first poll, a slice
        at a time (the loop keeps its turns); then the IOC's own values are
        posted (their records are UDF until then). Never raises: a route
        that fails here is made at its first value."""
        self.keep_chain(self.plan)
        attributes = self.target_attributes()
        channel_members = self.health.followers.with_followers(attributes)
        self.health.publisher.channels.add(
            a for a in channel_members if isinstance(a, AttrR)
        )
        for first in range(0, len(attributes), PREPARED_AT_ONCE):
            try:
                self.health.publisher.prepare(
                    attributes[first : first + PREPARED_AT_ONCE]
                )
            except Exception:
                logger.debug("routes not prepared", exc_info=True)
                break
            await asyncio.sleep(0)
        await self.health.publisher.start(self.own_attributes())

    def start(self) -> None:
        """The transports serve: poll, supervise, read the CoE values.

        CoE values are read now that every PV serves, not before: thousands
        of SDO uploads (mailbox round trips on a real bus) would hold up the
        start. Until read, each is INVALID (UDF).
        """
        plan = self.plan
        logger.info(
            "serving %d PVs of %d terminals on %d master(s)%s",
            self.pv_count,
            sum(len(m.terminals) for m in plan.masters),
            len(plan.masters),
            " (INVALID until the target answers)" if plan.offline_from else "",
        )
        if self.heartbeat is None:
            self.heartbeat = Heartbeat()
        self.heartbeat.stop_keeping_fresh()  # the 1 s health scan beats now
        self.start_count = count_start()
        coe = [a for t in self.terminals() for a in t.coe_attributes]
        self.health.mark_invalid(coe, COE_READ, Status.UDF, "not read yet")
        if plan.offline_from:
            self.health.mark_invalid(
                self.target_attributes(),
                COMM,
                Status.COMM,
                f"target not reached since start (served from {plan.offline_from})",
            )
        self.reconnection.start()

    async def disconnect(self) -> None:
        """Stop supervising and polling and close every ADS connection."""
        if self._reconnection is not None:
            await self._reconnection.stop()

    async def show_link(self, state: str, error: str) -> None:
        """Publish a change of the link at once, not at the next scan."""
        try:
            a = self.attrs
            await self.health.post(a["Connected"], state == "CONNECTED")
            await self.health.post(a["ConnectionState"], state)
            if error:
                await self.health.post(a["LastError"], error[:200])
        except Exception:  # never stop the caller (the supervisor)
            logger.debug("cannot show the link state", exc_info=True)

    @scan(STATS_PERIOD_S)
    async def read_stats(self) -> None:
        """Copy the pollers' and the supervisor's figures; never raises."""
        if self._reconnection is None:
            return
        try:
            await self._beat()
            await self._post_stats()
        except Exception:  # a scan must never raise
            logger.debug("cannot post the statistics", exc_info=True)

    async def _beat(self) -> None:
        """The heartbeat first: it must not wait on the figures below."""
        if self.heartbeat is not None:
            await self.health.post(self.attrs["Heartbeat"], self.heartbeat.beat())
        await self.health.post(self.attrs["StartCount"], self.start_count)

    async def _post_stats(self) -> None:
        stats = [s for master in self.masters for s in master.poll_stats()]
        self.rates.update(
            Totals(
                time.monotonic(),
                sum(s.cycles for s in stats),
                sum(s.requests for s in stats),
                self.health.publisher.posted,
            )
        )
        link = self.reconnection.supervisor.stats
        connected = self.reconnection.connection.connected
        errors = [s.last_error for s in stats if s.last_error]
        last_error = errors[0] if errors else ""
        if not connected or not last_error:
            last_error = link.last_error
        a = self.attrs
        await self.health.post(a["PvCount"], self.pv_count)
        await self.health.post(a["Unserved"], self.unserved)
        await self.health.post(
            a["Connected"],
            connected and bool(stats) and all(s.cycles > 0 for s in stats),
        )
        await self.health.post(
            a["PollCycleTime"],
            1000.0 * max((s.last_cycle_s for s in stats), default=0.0),
        )
        await self.health.post(a["PollRate"], self.rates.cycles_per_second)
        await self.health.post(a["AdsRequestRate"], self.rates.requests_per_second)
        await self.health.post(a["PostRate"], self.rates.posts_per_second)
        errors_total = sum(s.errors + s.item_errors for s in stats)
        await self.health.post(a["PollErrors"], min(errors_total, 2**31 - 1))
        await self.health.post(a["LastError"], last_error[:200])
        await self.health.post(a["ConnectionState"], str(link.state))
        await self.health.post(a["Reconnects"], min(link.reconnects, 2**31 - 1))
        await self.health.post(a["Resyncs"], min(link.resyncs, 2**31 - 1))
        await self.health.post(a["LastRecovery"], link.last_recovery_s)
        await self.health.post(a["ChainChanges"], self.reconnection.chain_changes[:200])
        await self.health.post(
            a["InvalidPvs"], min(self.health.invalid_count, 2**31 - 1)
        )
        live = self.reconnection.live
        await self.health.post(a["SymbolVersion"], live.symbol_version)
        await self.health.post(a["DeviceName"], live.device_name)
        await self.health.post(a["DeviceVersion"], live.device_version)
        sample = self.process.sample()
        await self.health.post(a["Uptime"], sample.uptime_s)
        await self.health.post(a["CpuLoad"], sample.cpu_percent)
        await self.health.post(a["MemoryUsed"], sample.memory_mib)
        await self.health.post(a["UptimeText"], sample.uptime_text)
        await self.health.post(a["IocCpuLoad"], sample.cpu_percent_of_all)
        await self.health.post(a["MemUsedBytes"], sample.memory_bytes)
        await self.health.post(
            a["PollOverruns"], min(sum(s.overruns for s in stats), 2**31 - 1)
        )


def fold_by_terminal(warnings: Sequence[str], terminals: Collection[str]) -> list[str]:
    """One line for what several terminals say alike (`Term 5 (EL3104): X`
    and `Term 29 (EL3104): X` -> `2 terminals (Term 5 (EL3104), Term 29
    (EL3104)): X`): a rack repeats its types, and so would its warnings."""
    by_text: dict[str, list[str]] = {}
    order: list[tuple[str, str]] = []
    for warning in warnings:
        name, colon, text = warning.partition(": ")
        if not colon or name not in terminals:
            order.append(("", warning))
            continue
        if text not in by_text:
            by_text[text] = []
            order.append((text, ""))
        by_text[text].append(name)
    folded: list[str] = []
    for text, warning in order:
        if not text:
            folded.append(warning)
            continue
        names = by_text[text]
        if len(names) == 1:
            folded.append(f"{names[0]}: {text}")
            continue
        folded.append(f"{len(names)} terminals ({first_names(names)}): {text}")
    return folded


def _root_attributes(
    plan: SystemPlan, target: str, process: ProcessStats
) -> dict[str, AttrR[Any, Any]]:
    terminals = sum(len(master.terminals) for master in plan.masters)
    return {
        "Connected": AttrR(
            AlarmBool(severities=(2, 0)), description="Polling the target"
        ),
        "Target": _fixed(String(), target, "ADS host[:port]"),
        "NetId": _fixed(String(), plan.net_id, "AMS NetId of the target"),
        "DeviceName": _fixed(String(), plan.device_name, "TwinCAT device name"),
        "DeviceVersion": _fixed(String(), plan.device_version, "TwinCAT version"),
        "SymbolVersion": _fixed(Int(), plan.symbol_version, "Symbol table version"),
        "Masters": _fixed(Int(), len(plan.masters), "EtherCAT masters served"),
        "Terminals": _fixed(Int(), terminals, "Terminals served"),
        "PvCount": AttrR(Int(), description="PVs served (CA names)"),
        "Unserved": AttrR(Int(), description="Points with no PV (see log)"),
        "PollCycleTime": _figure("ms", 2, "Last poll cycle"),
        "PollRate": _figure("Hz", 1, "Poll cycles per second"),
        "AdsRequestRate": _figure("1/s", 1, "ADS requests per second"),
        "PostRate": _figure("1/s", 1, "Polled values posted per s"),
        "PollErrors": AttrR(Int(), description="Failed poll reads"),
        "LastError": AttrR(String(), description="Last ADS error"),
        "ConnectionState": AttrR(
            alarm_enum(LinkState, LINK_SEVERITIES),
            initial_value=LinkState.DISCONNECTED,
            description="Link to the target",
        ),
        "Reconnects": AttrR(Int(), description="Outages ended (reconnects)"),
        "Resyncs": AttrR(Int(), description="Symbols resolved again"),
        "LastRecovery": _figure("s", 2, "Last outage, loss to poll"),
        "ChainChanges": AttrR(String(), description="Chain change at reconnect"),
        "InvalidPvs": AttrR(Int(), description="Attributes in INVALID alarm"),
        "Version": _fixed(String(), __version__, "fastcs-ethercat version"),
        "StartTime": _fixed(String(), process.start_text(), "IOC start (local time)"),
        "Uptime": _figure("s", 0, "Seconds since IOC start"),
        "CpuLoad": _figure("%", 1, "IOC CPU, % of one core"),
        "MemoryUsed": _figure("MiB", 1, "IOC resident memory"),
        "PollOverruns": AttrR(
            Int(), description="Poll cycles longer than their period"
        ),
        "Heartbeat": AttrR(Int(), description="Counts the 1 s health scans"),
        "UptimeText": AttrR(String(), description="Uptime as D days, HH:MM:SS"),
        "IocCpuLoad": _figure("%", 1, "IOC CPU, % of all its cores"),
        "MemUsedBytes": _figure("byte", 0, "IOC resident memory"),
        "StartCount": AttrR(Int(), description="IOC starts (runtime folder)"),
    }


def _figure(units: str, prec: int, text: str) -> AttrR[Any, Any]:
    """A measured figure (a time, rate or load) in `units`."""
    return AttrR(ExactFloat(units=units, prec=prec), description=text)


def _fixed(datatype: Any, value: Any, text: str) -> AttrR[Any, Any]:
    """An attribute whose value is known before serving and never changes."""
    return AttrR(datatype, initial_value=datatype.validate(value), description=text)
