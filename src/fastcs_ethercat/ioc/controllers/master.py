"""One controller per EtherCAT master: its terminals, its pollers, its writes.

The master owns everything between its ADS device and its attributes:

- a typed map of its terminal controllers (by slave address) and of every
  attribute a polled point feeds (by point key);
- the symbol handles its points are read and written by (`ioc.handles`),
  taken whenever polling starts and given back when it stops; a handle that
  went invalid (an online change) asks the supervisor to resolve again;
- one `Poller` per poll rate, whose changes it posts straight to the
  attributes through `Health` (value path: poller -> decode -> master ->
  attribute -> publisher);
- the write path of its outputs (`write`): checked, sent by handle, never
  queued behind others; held through an online change and sent by the new
  handle; of unknown outcome, read back once the target answers; what the
  setpoints then show is `Setpoints`' call;
- `use_plan`, which re-resolves every point by key after a new discovery
  (online change, reconnect).

Its own queries (port 0xFFFF of the device's NetId) are slow-moving
diagnostics, read once a second in one scan that also hands every slave its
AL state, link state and CRC errors. Any failure is counted and shown, never
raised: an exception out of a scan would pause every scan of the tree.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import defaultdict
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Final

from fastcs.attributes import AttrR, AttrW
from fastcs.controllers import Controller
from fastcs.datatypes import Int, String
from fastcs.methods import scan

from fastcs_ethercat.ads.client import (
    AdsError,
    AdsHandleInvalidError,
    AdsTimeoutError,
    unreachable,
)
from fastcs_ethercat.ads.constants import (
    MASTER_STATE_OFFSET,
    AmsPort,
    EtherCatMasterGroup,
    describe_return_code,
)
from fastcs_ethercat.ads.errors import HANDLE_ERRORS
from fastcs_ethercat.ads.ethercat import (
    CrcCounters,
    FrameCounters,
    SlaveState,
    decode_master_state,
    decode_slave_count,
    decode_slave_states,
)
from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.attributes import (
    PointIO,
    attribute_for_point,
    engineering_value,
    enum_of,
    from_device,
)
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.controllers.terminal import (
    AL_STATE_SEVERITIES,
    AlStateView,
    TerminalController,
    al_state_view,
)
from fastcs_ethercat.ioc.datatypes import AlarmBool, IntegralFloat, alarm_enum
from fastcs_ethercat.ioc.encode import pack_write
from fastcs_ethercat.ioc.handles import PointHandles, acquire, release
from fastcs_ethercat.ioc.health import COMM, READ, Health
from fastcs_ethercat.ioc.plan import MasterPlan, Point, TerminalPlan
from fastcs_ethercat.ioc.poller import Poller, PollStats
from fastcs_ethercat.ioc.setpoints import Setpoints
from fastcs_ethercat.ioc.supervisor import LinkState
from fastcs_ethercat.ioc.tasks import cancel_and_wait

logger = logging.getLogger(__name__)

DIAGNOSTICS_PERIOD_S: Final = 1.0
HOLD_S: Final = 2.0
"""How long a write refused by an online change waits for the new handles."""
HOLD_POLL_S: Final = 0.01
SETTLE_POLL_S: Final = 0.05
"""How often a write of unknown outcome looks whether the target answers."""
CRC_EVERY: Final = 5
"""CRC counters take one read per slave: read them every 5th scan only."""
MASTER_LEAVES: Final = (
    "NetId",
    "State",
    "SlaveCount",
    "ExpectedSlaves",
    "Online",
    "CyclicFrames",
    "CyclicLost",
    "AcyclicFrames",
    "AcyclicLost",
    "LostFrames",
    "DiagErrors",
)


@dataclass
class MasterStatus:
    """One reading of the master's diagnostics."""

    state: int
    slave_count: int
    frames: FrameCounters
    slave_states: tuple[SlaveState, ...]
    crc: dict[int, int] = field(default_factory=dict)
    """Sum of the four port counters, by slave address."""


MasterReader = Callable[[], Awaitable[MasterStatus]]
Batch = list[tuple[Point, Any]]
"""One poll cycle's changes."""


class MasterAds:
    """Reads a master's diagnostics from `<netid>:0xFFFF`, through the
    connection's client of the moment, only while the target answers."""

    def __init__(
        self, connection: Connection, net_id: str, addresses: list[int]
    ) -> None:
        self.connection = connection
        self.net_id = net_id
        self.addresses = addresses
        self.reads = 0

    async def __call__(self) -> MasterStatus:
        self.connection.check_readable()
        client = await self.connection.client(self.net_id, AmsPort.ETHERCAT_MASTER)
        group = EtherCatMasterGroup
        state = decode_master_state(
            await client.read(group.MASTER_STATE, MASTER_STATE_OFFSET, 2)
        )
        count = decode_slave_count(await client.read(group.SLAVE_COUNT, 0, 2))
        frames = FrameCounters.decode(await client.read(group.FRAME_COUNTERS, 0, 20))
        states = decode_slave_states(
            await client.read(group.SLAVE_STATES, 0, 2 * count)
        )
        crc: dict[int, int] = {}
        if self.reads % CRC_EVERY == 0:
            crc = await self._crc_counters(client)
        self.reads += 1
        return MasterStatus(state, count, frames, states, crc)

    async def _crc_counters(self, client: Any) -> dict[int, int]:
        """Every slave's CRC errors (all ports); one read each, as the master
        answers no sum reads. A slave that does not answer is left out."""
        crc: dict[int, int] = {}
        for address in self.addresses:
            try:
                raw = await client.read(
                    EtherCatMasterGroup.SLAVE_CRC_COUNTERS, address, 16
                )
            except Exception:
                continue
            counters = CrcCounters.decode(raw)
            crc[address] = (
                counters.port_a + counters.port_b + counters.port_c + counters.port_d
            )
        return crc


@dataclass
class PollGroup:
    """One poll loop of a master: the points it polls at one rate."""

    rate_hz: float
    points: list[Point]
    poller: Poller | None = None


class MasterController(Controller):
    """An EtherCAT master: its counters, its terminals, its pollers, its writes."""

    def __init__(
        self,
        plan: MasterPlan,
        leaves: Mapping[str, str],
        connection: Connection,
        health: Health,
        *,
        read_only: bool = False,
    ) -> None:
        self.point_io = PointIO(self.write)
        super().__init__(description=plan.name, ios=[self.point_io])
        self.plan = plan
        self.connection = connection
        self.health = health
        self.reader: MasterReader | None = MasterAds(
            connection, plan.net_id, [t.slave.address for t in plan.terminals]
        )
        self.terminals: dict[int, TerminalController] = {}
        """Every terminal (and coupler) controller below, by slave address."""
        self.terminal_positions: dict[int, int] = {
            t.slave.address: t.slave.position for t in plan.terminals
        }
        self.attributes_by_key: dict[str, AttrR[Any, Any]] = {}
        """Every attribute a polled point feeds, terminals' included, by key."""
        self.shown_by_key: dict[str, AttrR[Any, Any]] = {}
        """Every attribute that shows a point to clients, by key: a scaled
        point's engineering value (fed through its raw twin), which clients
        write and whose setpoints show the writes."""
        self.groups: list[PollGroup] = []
        self.points: dict[str, Point] = {}
        """Point key -> the point as the target has it now (offsets move)."""
        self.symbol_port = plan.symbol_port
        """The device's ADS port as discovered last (sum reads and writes)."""
        self.handles = self._no_handles = PointHandles()
        """The handles of the points polled now (taken when polling starts;
        `_no_handles` while none are: between a resync's two sets)."""
        self.setpoints = Setpoints(health)
        self._generation = 0
        """Counts the handle sets taken and given back: a write that failed
        on an older set asks for no resync (one is under way or done)."""
        self._taken = 0
        """Counts the handle sets taken (a held write waits for the next)."""
        self._puts: dict[str, int] = {}
        """Point key -> number of its latest put (a later one supersedes)."""
        self._settling: dict[str, asyncio.Task[None]] = {}
        """Point key -> the readback deciding its write of unknown outcome."""
        self._group_of: dict[str, PollGroup] = {}
        self._tasks: list[asyncio.Task[Any]] = []
        self.unserved: list[tuple[str, str]] = []
        self.failures = 0
        self.last_error = ""
        attrs: dict[str, AttrR[Any, Any]] = {
            "NetId": AttrR(
                String(), initial_value=plan.net_id, description="Master's AMS NetId"
            ),
            "State": AttrR(
                alarm_enum(AlStateView, AL_STATE_SEVERITIES),
                description="EtherCAT master state",
            ),
            "SlaveCount": AttrR(Int(), description="Slaves the master sees"),
            "ExpectedSlaves": AttrR(
                Int(),
                initial_value=len(plan.terminals),
                description="Slaves found at start",
            ),
            "Online": AttrR(
                AlarmBool(severities=(2, 0)), description="Master diagnostics answer"
            ),
            "CyclicFrames": AttrR(IntegralFloat(), description="Cyclic frames"),
            "CyclicLost": AttrR(IntegralFloat(), description="Lost cyclic frames"),
            "AcyclicFrames": AttrR(IntegralFloat(), description="Acyclic frames"),
            "AcyclicLost": AttrR(IntegralFloat(), description="Lost acyclic frames"),
            "LostFrames": AttrR(IntegralFloat(), description="Lost frames, all"),
            "DiagErrors": AttrR(Int(), description="Failed diagnostics reads"),
        }
        self.attrs = attrs
        for leaf, attr in attrs.items():
            self.add_attribute(leaves[leaf], attr)
        for point in plan.master_points:
            try:
                attr = attribute_for_point(point, read_only=read_only)
            except ValueError as error:
                self.unserved.append((point.symbol, str(error)))
                continue
            self.add_attribute(leaves[point.symbol], attr)
            assert isinstance(attr, AttrR)
            self.attributes_by_key[point.key] = self.shown_by_key[point.key] = attr

    def add_terminal(self, terminal: TerminalController) -> None:
        """A terminal below this master (added to its parent by the builder)."""
        self.terminals[terminal.plan.slave.address] = terminal
        self.attributes_by_key.update(terminal.by_key)
        self.shown_by_key.update(terminal.shown_by_key)

    # -- polling -------------------------------------------------------------------

    def use_plan(
        self, plan: MasterPlan, rate_of: Callable[[TerminalPlan | None], float]
    ) -> tuple[list[AttrR[Any, Any]], list[AttrR[Any, Any]]]:
        """Poll the points of `plan` (the master as discovered now) that this
        tree serves in the same shape; (attributes gone, attributes served).

        Points are matched by key, so offsets may move; bus positions are
        taken from `plan` too (the master reports slave states by position).
        """
        built = {p.key: p for p in self._built_points()}

        def keep(point: Point) -> bool:
            old = built.get(point.key)
            return (
                point.key in self.attributes_by_key
                and old is not None
                and _same_shape(old, point)
            )

        by_rate: dict[float, list[Point]] = defaultdict(list)
        by_rate[rate_of(None)] += plan.master_points
        for terminal in plan.terminals:
            by_rate[rate_of(terminal)] += terminal.points
            if terminal.slave.address in self.terminal_positions:
                self.terminal_positions[terminal.slave.address] = (
                    terminal.slave.position
                )
        self.symbol_port = plan.symbol_port or self.symbol_port
        self.groups = []
        for rate, points in sorted(by_rate.items()):
            kept = [p for p in points if keep(p)]
            if kept:
                self.groups.append(PollGroup(rate, kept))
        self._group_of = {p.key: g for g in self.groups for p in g.points}
        self.points = {p.key: p for g in self.groups for p in g.points}
        gone = [a for k, a in self.attributes_by_key.items() if k not in self.points]
        served = [a for k, a in self.attributes_by_key.items() if k in self.points]
        return gone, served

    def _built_points(self) -> list[Point]:
        points = list(self.plan.master_points)
        for terminal in self.terminals.values():
            points += terminal.plan.points
        return points

    async def start_polling(self) -> None:
        """Handles for every point, one poller task per rate, one task posting
        its changes; the outputs' setpoints wait for the PLC's values.

        The poller hands on each cycle's changes synchronously; they are
        queued and posted in order, so a slow cycle of posting never runs two
        batches at once, and one cycle's values are processed together.
        """
        client = await self.connection.client(self.connection.net_id, self.symbol_port)
        served = [p for g in self.groups for p in g.points]
        self.handles = await acquire(
            client, served, writes=not self.connection.read_only
        )
        self._generation += 1
        self._taken += 1
        self._unreadable(served)
        self.setpoints.follow(
            a for k, a in self.shown_by_key.items()
            if k in self.points and self.points[k].writable and isinstance(a, AttrW)
        )  # fmt: skip
        for group in self.groups:
            batches: asyncio.Queue[Batch] = asyncio.Queue()

            def on_changes(
                changes: Batch, queue: asyncio.Queue[Batch] = batches
            ) -> None:
                queue.put_nowait(changes)

            readable = [p for p in group.points if p.source_name in self.handles.reads]
            group.poller = Poller(
                client, readable, self.handles.reads, on_changes, self.note_errors
            )
            self._tasks.append(asyncio.create_task(self._post_batches(batches)))
            self._tasks.append(asyncio.create_task(group.poller.run(group.rate_hz)))

    def _unreadable(self, points: list[Point]) -> None:
        """Points without a read handle go INVALID/READ (not polled); a source
        the table no longer has as discovery saw it asks for a resync."""
        by_problem: dict[str, list[AttrR[Any, Any]]] = defaultdict(list)
        for point in points:
            problem = self.handles.read_problem(point)
            attr = self.attributes_by_key.get(point.key)
            if problem is not None and attr is not None:
                by_problem[f"{point.source_name}: {problem}"].append(attr)
        for problem, attrs in by_problem.items():
            self.health.mark_invalid(attrs, READ, Status.READ, problem)
        if by_problem:
            first = next(iter(by_problem))
            logger.warning(
                "%s: %d symbols not readable by handle (%s)",
                self.plan.name,
                len(by_problem),
                first,
            )
            self.connection.resync(f"{len(by_problem)} symbols changed ({first})")

    async def stop_polling(self) -> None:
        """Stop every poller and its posting task (before the clients go);
        give the handles back while the target answers (unless read-only)."""
        for group in self.groups:
            if group.poller is not None:
                group.poller.stop()
        tasks, self._tasks = self._tasks, []
        await cancel_and_wait(tasks)
        old, self.handles = self.handles.all(), self._no_handles
        self._generation += 1
        if (
            old
            and not self.connection.read_only  # never an ADS write, not even this
            and self.connection.state is not LinkState.DISCONNECTED
        ):
            try:
                client = await self.connection.client(
                    self.connection.net_id, self.symbol_port
                )
            except (AdsError, OSError):
                return
            await release(client, old)

    def poll_stats(self) -> list[PollStats]:
        return [g.poller.stats for g in self.groups if g.poller is not None]

    async def _post_batches(self, batches: asyncio.Queue[Batch]) -> None:
        """Each cycle's changes posted together (one lock for its CA records)."""
        attributes, health = self.attributes_by_key, self.health
        enums: dict[Any, Any] = {}  # an attribute's enum class, None: no enum
        while True:
            changes = await batches.get()
            values: list[tuple[AttrR[Any, Any], Any]] = []
            for point, value in changes:
                attr = attributes.get(point.key)
                if attr is None:
                    continue
                if point.key not in enums:
                    enums[point.key] = enum_of(attr)
                try:
                    if enums[point.key] is not None:
                        value = from_device(attr, value)
                    values.append((attr, value))
                except Exception as error:  # one value must not stop the others
                    self._failed(point.symbol, error)
            for attr, error in (await health.post_batch(values)).failures:
                self._failed(attr.full_name or attr.name, error)

    def _failed(self, what: str, error: Exception) -> None:
        self.failures += 1
        self.last_error = f"{what}: {type(error).__name__}: {error}"

    def note_errors(self, errors: list[tuple[Point, int]]) -> None:
        """Points whose read failed this cycle: only they go into alarm (their
        values are not published); invalid handles ask for a resync."""
        by_code: dict[int, list[AttrR[Any, Any]]] = defaultdict(list)
        for point, code in errors:
            attr = self.attributes_by_key.get(point.key)
            if attr is not None:
                by_code[code].append(attr)
        for code, attrs in by_code.items():
            if unreachable(code):  # no answer: the target, not the point
                reason, status = COMM, Status.COMM
            else:
                reason, status = READ, Status.READ
            self.health.mark_invalid(attrs, reason, status, describe_return_code(code))
        stale = HANDLE_ERRORS & by_code.keys()
        if stale:
            self.connection.resync(
                f"symbol handles invalid ({describe_return_code(min(stale))})"
            )
        if len(errors) >= len(self.points):
            self.connection.wake()  # the whole read failed: is the target there?

    # -- writes --------------------------------------------------------------------

    async def write(self, point: Point, value: Any) -> None:
        """One write from a client: checked, sent by the handle of the point's
        symbol, never queued behind others.

        Refused while the IOC is read-only or the target is away, and when
        the point has no handle. One refused because the symbol table changed
        (an online change) is held until the master has resolved again, for
        at most HOLD_S, and sent with the new handle if its symbol is still
        there with its type and size; a later put on the same output
        replaces it. One whose outcome is unknown (no answer, the link lost
        while in flight) is read back once the target answers again, and the
        readback decides. Whatever did not reach the PLC is logged and raised
        (the client's put fails) and its setpoints say so (`Setpoints`).
        """
        attr = self.shown_by_key.get(point.key)
        shown = _fastcs_value(attr, engineering_value(point, value))
        put = self._puts[point.key] = self._puts.get(point.key, 0) + 1
        settling = self._settling.pop(point.key, None)
        if settling is not None:
            settling.cancel()  # this put decides the setpoint now
        try:
            try:
                await self._deliver(point, value, put)
            except OutcomeUnknownError as unknown:
                await self._decided_now(point, unknown)
        except SupersededError as error:
            logger.info("write of %r to %s: %s", value, point.symbol, error)
            raise
        except OutcomeUnknownError as error:
            logger.error("write of %r to %s: %s", value, point.symbol, error)
            if attr is not None:
                await self.setpoints.unknown(attr, shown, str(error))
                self._settle_later(point, attr, shown, put, error.data)
            raise
        except Exception as error:
            why = _why(error)
            logger.error("write of %r to %s failed: %s", value, point.symbol, why)
            if attr is not None:
                await self.setpoints.failed(
                    attr, shown, f"not written: {why}", self._reread(point)
                )
            if isinstance(error, AdsError):  # its text names a handle: name the symbol
                raise WriteError(f"{point.symbol} not written: {why}") from error
            raise
        if attr is not None:
            await self.setpoints.written(attr, shown)

    async def _decided_now(self, point: Point, unknown: OutcomeUnknownError) -> None:
        """A write not answered, read back at once where the target answers
        (the target answers in order: the read sees the write if it landed);
        raises `unknown` when it cannot say yet."""
        now = await self._read_back(point, len(unknown.data))
        if now is None:
            raise unknown
        if isinstance(now, str):
            raise WriteError(f"no answer, and {now}") from unknown
        if now != unknown.data:
            raise WriteError(
                "no answer, and the read back shows it was not applied"
            ) from unknown
        logger.warning("write to %s: no answer but applied (read back)", point.symbol)

    async def _deliver(self, point: Point, value: Any, put: int) -> None:
        """Send; while the symbol table is being resolved again (or a handle
        answers that it changed), wait for the new handles and send again."""
        if self.connection.read_only:
            raise PermissionError("read-only IOC: no ADS writes")
        deadline = time.monotonic() + HOLD_S
        while True:
            taken = self._taken
            try:
                await self._send(point, value)
                return
            except TableChangedError as error:
                if not await self._resolved_since(taken, deadline):
                    raise TableChangedError(
                        f"{error}; not resolved again within {HOLD_S:g} s"
                    ) from error.cause
                if self._puts.get(point.key) != put:
                    raise SupersededError("replaced by a later put") from None
                logger.info("write to %s: sent again after resolving", point.symbol)

    async def _send(self, point: Point, value: Any) -> None:
        """One attempt by the current handle (TableChangedError: the table is
        being resolved again, or the handle is no longer valid)."""
        if self.connection.state is LinkState.RESYNCING:
            raise TableChangedError("the symbol table is being resolved again")
        self.connection.check_writable(f"write to {point.symbol}")
        live = self.points.get(point.key)
        group = self._group_of.get(point.key)
        if live is None or group is None:
            raise LookupError(f"{point.symbol} is not on the target any more")
        handle = self.handles.writes.get(point.symbol)
        if self.handles is self._no_handles:  # between two sets
            raise TableChangedError("the symbol handles are being taken again")
        problem = self.handles.write_problem(point) or self.handles.problems.get(
            live.source_name
        )  # its structure changed: no member of it is written
        if handle is None or problem is not None:
            raise LookupError(f"{point.symbol}: {problem or 'no handle'}")
        data = pack_write(live, value)
        generation = self._generation
        client = await self.connection.client(self.connection.net_id, self.symbol_port)
        try:
            await client.write_by_handle(handle, data)
        except AdsHandleInvalidError as error:
            if generation == self._generation:
                self.connection.resync(f"write to {point.symbol}: handle invalid")
            raise TableChangedError(_why(error), error) from error
        except AdsError as error:
            if not unreachable(error.code):
                raise
            raise OutcomeUnknownError(
                f"outcome unknown: {_no_answer(error)}; read back once the "
                "target answers",
                data,
            ) from error
        if group.poller is not None:
            group.poller.invalidate()  # the readback shows what the PLC holds

    async def _resolved_since(self, taken: int, deadline: float) -> bool:
        """Wait (until `deadline`) for a handle set taken after set `taken`
        with the resolving over."""
        while time.monotonic() < deadline:
            if self._taken > taken and self.connection.state is not (
                LinkState.RESYNCING
            ):
                return True
            await asyncio.sleep(HOLD_POLL_S)
        return False

    def _settle_later(
        self, point: Point, attr: AttrR[Any, Any], shown: Any, put: int, data: bytes
    ) -> None:
        task = asyncio.create_task(self._settle(point, attr, shown, put, data))
        self._settling[point.key] = task
        task.add_done_callback(
            lambda t, key=point.key: (
                self._settling.pop(key, None) if self._settling.get(key) is t else None
            )
        )

    async def _settle(
        self, point: Point, attr: AttrR[Any, Any], shown: Any, put: int, data: bytes
    ) -> None:
        """A write of unknown outcome: read its symbol back as soon as the
        target answers (by the handle of the moment: a reconnect takes new
        ones) and let the readback decide what the setpoints show. A later
        put on the same output decides instead."""
        while self._puts.get(point.key) == put:
            now = await self._read_back(point, len(data))
            if self._puts.get(point.key) != put:
                return
            if isinstance(now, str):
                logger.error("write to %s: %s", point.symbol, now)
                await self.setpoints.failed(
                    attr, shown, f"not written: {now}", self._reread(point)
                )
                return
            if now is not None:
                if now == data:
                    logger.warning("write to %s: applied (read back)", point.symbol)
                    await self.setpoints.written(attr, shown)
                else:
                    logger.error("write to %s: not applied (read back)", point.symbol)
                    await self.setpoints.failed(
                        attr,
                        shown,
                        "not written: the PLC holds another value",
                        self._reread(point),
                    )
                return
            await asyncio.sleep(SETTLE_POLL_S)

    def _reread(self, point: Point) -> Callable[[], None]:
        """Asks the poller of `point` (as polled then) to report its group's
        values on its next cycle, changed or not: the readback that shows
        whether the PLC holds a failed write's value all the same."""

        def reread() -> None:
            group = self._group_of.get(point.key)
            if group is not None and group.poller is not None:
                group.poller.invalidate()

        return reread

    async def _read_back(self, point: Point, size: int) -> bytes | str | None:
        """The symbol's bytes now; None while the target cannot say (away,
        resolving, no answer); why not, where it never will (gone, changed)."""
        if not self.connection.connected:
            return None
        live = self.points.get(point.key)
        if live is None:
            return f"{point.symbol} is not on the target any more"
        handle = self.handles.writes.get(point.symbol)
        problem = self.handles.write_problem(point) or self.handles.problems.get(
            live.source_name
        )  # its structure changed: no member of it is written
        if handle is None or problem is not None:
            return (
                None
                if self.handles is self._no_handles
                else f"{point.symbol}: {problem}"
            )
        try:
            client = await self.connection.client(
                self.connection.net_id, self.symbol_port
            )
            return await client.read_by_handle(handle, size)
        except AdsHandleInvalidError:
            return None  # an online change: the resync takes new handles
        except AdsError as error:
            if unreachable(error.code):
                return None
            return f"read back refused ({describe_return_code(error.code)})"

    # -- diagnostics ---------------------------------------------------------------

    @scan(DIAGNOSTICS_PERIOD_S)
    async def read_diagnostics(self) -> None:
        """Master counters and every slave's state; never raises."""
        if self.reader is None:
            return
        try:
            status = await self.reader()
        except Exception as error:  # keep the scans of the tree going
            self.failures += 1
            self.last_error = f"{type(error).__name__}: {error}"
            await self._safe_post("Online", False)
            await self._safe_post("DiagErrors", min(self.failures, 2**31 - 1))
            return
        try:
            await self.apply_status(status)
        except Exception as error:
            self.failures += 1
            self.last_error = f"{type(error).__name__}: {error}"

    async def apply_status(self, status: MasterStatus) -> None:
        frames = status.frames
        a = self.attrs
        fresh = self.health.post
        await fresh(a["Online"], True)
        await fresh(a["State"], master_state_view(status.state))
        await fresh(a["SlaveCount"], status.slave_count)
        await fresh(a["CyclicFrames"], frames.cyclic_sent)
        await fresh(a["CyclicLost"], frames.cyclic_lost)
        await fresh(a["AcyclicFrames"], frames.acyclic_sent)
        await fresh(a["AcyclicLost"], frames.acyclic_lost)
        await fresh(a["LostFrames"], frames.cyclic_lost + frames.acyclic_lost)
        await self.health.post(a["DiagErrors"], min(self.failures, 2**31 - 1))
        for address, terminal in self.terminals.items():
            position = self.terminal_positions.get(address, -1)
            state = (
                status.slave_states[position]
                if 0 <= position < len(status.slave_states)
                else None
            )
            try:
                await terminal.set_diagnostics(state, status.crc.get(address))
            except Exception:  # one terminal must not stop the rest
                self.failures += 1

    def target_attributes(self) -> list[AttrR[Any, Any]]:
        """What goes invalid when the target is lost (not what the IOC knows):
        this master's points and diagnostics, and its terminals'."""
        own = {"NetId", "ExpectedSlaves", "Online", "DiagErrors"}
        found = [attr for leaf, attr in self.attrs.items() if leaf not in own]
        found += [self.attributes_by_key[p.key] for p in self.plan.master_points
                  if p.key in self.attributes_by_key]  # fmt: skip
        for terminal in self.terminals.values():
            found += terminal.target_attributes()
        return found

    async def _safe_post(self, leaf: str, value: Any) -> None:
        try:
            await self.health.post(self.attrs[leaf], value)
        except Exception:
            self.failures += 1


def master_state_view(state: int) -> AlStateView:
    """The master's state word as the states a slave reports (OP ...)."""
    return al_state_view(SlaveState(state & 0xFF))


class OutcomeUnknownError(TimeoutError):
    """A write not answered (no answer in time, the link lost while it was in
    flight): it may have landed. `data`: the bytes sent."""

    def __init__(self, message: str, data: bytes) -> None:
        super().__init__(message)
        self.data = data


class TableChangedError(RuntimeError):
    """A write refused because the symbol table changed or is being resolved
    again: held until the new handles are taken."""

    def __init__(self, message: str, cause: Exception | None = None) -> None:
        super().__init__(message)
        self.cause = cause


class SupersededError(RuntimeError):
    """A held write that a later put on the same output replaced."""


class WriteError(RuntimeError):
    """A write the target did not take."""


def _no_answer(error: AdsError) -> str:
    if isinstance(error, AdsTimeoutError):
        return f"no answer ({describe_return_code(error.code)})"
    return f"the link went while it was in flight ({describe_return_code(error.code)})"


def _why(error: Exception) -> str:
    """Why a write failed, in a few words."""
    if isinstance(error, AdsHandleInvalidError):
        return f"the symbol table changed ({describe_return_code(error.code)})"
    if isinstance(error, AdsError):
        return describe_return_code(error.code)
    return str(error) or type(error).__name__


def _fastcs_value(attr: AttrR[Any, Any] | None, value: Any) -> Any:
    """A written device value as the attribute's setpoints show it."""
    if attr is None:
        return value
    try:
        return attr.datatype.validate(from_device(attr, value))
    except Exception:  # shown as it came: the write itself will say why
        return value


def _same_shape(old: Point, new: Point) -> bool:
    """The attribute made for `old` can serve `new` (same type, same form)."""
    return (
        old.type_name == new.type_name
        and old.kind is new.kind
        and old.length == new.length
        and old.bit_size == new.bit_size
        and old.writable == new.writable
    )
