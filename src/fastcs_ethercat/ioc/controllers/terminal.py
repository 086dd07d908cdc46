"""One controller per EtherCAT slave: its selected symbols, diagnostics, CoE.

Symbols arrive as changed values from the master's poller, posted by the
master straight to the attributes in `by_key`; diagnostics (AL state, link
state, CRC errors) from the master controller's slow scan
(`set_diagnostics`); CoE objects are read once at start and again when
`CoeRefresh` is pressed, never polled. Nothing here raises out of a scan.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from typing import Any, Final

from fastcs.attributes import Attribute, AttrR
from fastcs.controllers import Controller
from fastcs.datatypes import Int, String
from fastcs.methods import Command

from fastcs_ethercat.ads.ethercat import AlState, AlStateFlag, SlaveState
from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.attributes import (
    CoeIO,
    CoeRef,
    PointIO,
    attribute_for_coe,
    attribute_for_point,
    from_device,
    raw_twin,
    to_engineering,
)
from fastcs_ethercat.ioc.datatypes import AlarmBool, alarm_enum
from fastcs_ethercat.ioc.health import COMM, Health
from fastcs_ethercat.ioc.naming import coe_leaf
from fastcs_ethercat.ioc.plan import CoePoint, Point, TerminalPlan
from fastcs_ethercat.terminals.meaning import RAW_SUFFIX

DIAGNOSTIC_LEAVES: Final = (
    "AlState",
    "AlStateText",
    "LinkOk",
    "LinkState",
    "CrcErrors",
    "Type",
)
"""Attributes every terminal controller has besides its symbols (PV leaves)."""
COE_REFRESH_LEAF: Final = "CoeRefresh"
UNKNOWN_TYPE: Final = "unknown"
SLAVE: Final = "slave"
"""Health reason: the terminal is not in OP or lost its link."""
COE_READ: Final = "coe"
"""Health reason: a CoE value could not be read again after an outage."""


PvPlace = tuple[str, ...]
"""Where an attribute sits below its terminal: its sub-controller's segment
(a channel, a CoE object), if any, then its own (`("CH1", "Value")`)."""


def raw_leaf(point: Point) -> str:
    """The leaf of a scaled point's raw twin: `...Value Raw` -> `...ValueRaw`."""
    return point.symbol + RAW_SUFFIX


class AlStateView(enum.Enum):
    """The AL state as an mbbi an operator can read with plain `caget`:
    the state, with `_ERR` when the slave flags an error."""

    UNKNOWN = "UNKNOWN"
    INIT = "INIT"
    PREOP = "PREOP"
    BOOT = "BOOT"
    SAFEOP = "SAFEOP"
    OP = "OP"
    INIT_ERR = "INIT_ERR"
    PREOP_ERR = "PREOP_ERR"
    BOOT_ERR = "BOOT_ERR"
    SAFEOP_ERR = "SAFEOP_ERR"
    OP_ERR = "OP_ERR"


AL_STATE_SEVERITIES: Final = {
    state: 0 if state is AlStateView.OP else 2 for state in AlStateView
}
"""A slave out of OP (or in OP with its error flag) is MAJOR."""


def al_state_view(state: SlaveState) -> AlStateView:
    """The enum value of `AlState` for what the master reports."""
    al = state.al_state
    if not isinstance(al, AlState) or al.name not in AlStateView.__members__:
        return AlStateView.UNKNOWN
    suffix = "_ERR" if state.flags & AlStateFlag.ERROR else ""
    return AlStateView[al.name + suffix]


def al_state_text(state: SlaveState) -> str:
    """`OP`, `SAFEOP+ERR`, ...: the AL state and its error flags, for humans."""
    al = state.al_state
    text = al.name if isinstance(al, AlState) else f"0x{int(al):X}"
    flags = state.flags
    if flags & AlStateFlag.ERROR:
        text += "+ERR"
    if flags & AlStateFlag.INVALID_VPRS:
        text += "+VPRS"
    if flags & AlStateFlag.INIT_COMMAND_ERROR:
        text += "+INITCMD"
    if flags & AlStateFlag.DISABLED:
        text += "+DISABLED"
    return text


class TerminalController(Controller):
    """A terminal whose type has a YAML: the symbols and CoE objects it selects.

    `places` maps a point's symbol (or a diagnostic / CoE leaf) to where its
    PV sits below the terminal, as planned by `naming`.
    """

    def __init__(
        self,
        plan: TerminalPlan,
        places: Mapping[str, PvPlace],
        point_io: PointIO,
        coe_io: CoeIO | None = None,
        *,
        read_only: bool = False,
        health: Health | None = None,
    ) -> None:
        ios: list[Any] = [point_io] if coe_io is None else [point_io, coe_io]
        super().__init__(description=_describe(plan), ios=ios)
        self._ios = ios
        self._places = places
        self.plan = plan
        self.health = health or Health()
        self.slave_problem = ""
        """Why the slave's points are in alarm ("" when it is in OP, linked)."""
        self.coe_io = coe_io
        if coe_io is not None:
            coe_io.read_back = self.read_coe
        self.by_key: dict[str, AttrR[Any, Any]] = {}
        """Point key -> the attribute it feeds (the master posts to it): a
        scaled point's raw twin, which its engineering value follows."""
        self.shown_by_key: dict[str, AttrR[Any, Any]] = {}
        """Point key -> the attribute that shows its value (a scaled point's
        engineering value): what clients write, whose setpoint shows writes."""
        self.coe_attributes: list[AttrR[Any, Any]] = []
        self.parts: dict[str, Controller] = {}
        """Its channels and CoE objects by segment, in the order first used."""
        self.unserved: list[tuple[str, str]] = []
        """(source, reason) of every point this terminal could not serve."""
        for point in plan.points:
            self._add_point(point, read_only)
        for coe in plan.coe if coe_io is not None else ():
            self._add_coe(coe, read_only)
        self.diag: dict[str, AttrR[Any, Any]] = {
            "AlState": AttrR(
                alarm_enum(AlStateView, AL_STATE_SEVERITIES), description="AL state"
            ),
            "AlStateText": AttrR(String(), description="AL state and flags"),
            "LinkOk": AttrR(
                AlarmBool(severities=(2, 0)),
                description="Own link fine (ports B-D: neighbours)",
            ),
            "LinkState": AttrR(Int(min=0, max=255), description="Link bits"),
            "CrcErrors": AttrR(Int(), description="CRC errors, all ports"),
            "Type": AttrR(
                String(),
                initial_value=plan.slave.type_name
                or plan.terminal_type
                or UNKNOWN_TYPE,
                description="Terminal type the master reports",
            ),
        }
        for leaf, attr in self.diag.items():
            self._place(leaf, attr)
        if self.coe_attributes:
            [name] = places[COE_REFRESH_LEAF]
            self.add_command(name, Command(self.refresh_coe))

    def _add_point(self, point: Point, read_only: bool) -> None:
        try:
            attr = attribute_for_point(point, read_only=read_only)
        except ValueError as error:
            self.unserved.append((point.symbol, str(error)))
            return
        assert isinstance(attr, AttrR)
        channel = f"Channel {point.channel}" if point.channel is not None else ""
        self._place(point.symbol, attr, channel)
        self.by_key[point.key] = self.shown_by_key[point.key] = attr
        raw = raw_twin(point)
        if raw is not None and point.scaling is not None:  # the poller feeds raw
            self._place(raw_leaf(point), raw, channel)
            self.health.follow(raw, attr, to_engineering(point.scaling))
            self.by_key[point.key] = raw

    def _add_coe(self, coe: CoePoint, read_only: bool) -> None:
        source = f"CoE {coe.index:04X}:{coe.subindex:02X} {coe.attribute}"
        try:
            attr: Attribute = attribute_for_coe(coe, read_only=read_only)
        except ValueError as error:
            self.unserved.append((source, str(error)))
            return
        title = f"CoE 0x{coe.index:04X} {coe.object_name}".rstrip()
        self._place(coe_leaf(coe.attribute), attr, title)
        assert isinstance(attr, AttrR)
        self.coe_attributes.append(attr)

    def _place(self, leaf: str, attr: Attribute, description: str = "") -> None:
        """Add `attr` where `places` puts it: here, or in the sub-controller of
        its channel or CoE object (made on first use, attached in `set_path`)."""
        place = self._places[leaf]
        if len(place) == 1:
            self.add_attribute(place[0], attr)
            return
        segment, name = place
        sub = self.parts.get(segment)
        if sub is None:
            sub = Controller(description=description or None, ios=self._ios)
            self.parts[segment] = sub
        sub.add_attribute(name, attr)

    def set_path(self, path: list[str]) -> None:
        """FastCS gives a sub-controller its path when it is added, from its
        parent's: the channels and CoE objects join once this has its own."""
        super().set_path(path)
        for segment, sub in self.parts.items():
            self.add_sub_controller(segment, sub)

    async def set_diagnostics(self, state: SlaveState | None, crc: int | None) -> None:
        """Post the master's view of this slave (None: not reported this time).

        A slave out of OP or cut off puts only its own points in alarm; a
        missing link on its port B, C or D is the neighbour's, not its own.
        """
        health = self.health
        if state is not None:
            await health.post(self.diag["AlState"], al_state_view(state))
            await health.post(self.diag["AlStateText"], al_state_text(state))
            await health.post(self.diag["LinkState"], state.link)
            await health.post(self.diag["LinkOk"], not state.link_state.own_fault())
            await self._judge(state)
        if crc is not None:
            await health.post(self.diag["CrcErrors"], min(crc, 2**31 - 1))

    async def _judge(self, state: SlaveState) -> None:
        problem = ""
        if state.al_state != AlState.OP:
            problem = f"{self.plan.slave.name} in {al_state_text(state)}"
        elif state.link_state.own_fault():
            problem = f"{self.plan.slave.name}: link lost (0x{state.link:02X})"
        if problem == self.slave_problem:
            return
        self.slave_problem = problem
        if problem:
            self.health.mark_invalid(self.by_key.values(), SLAVE, Status.STATE, problem)
        else:
            await self.health.mark_ok(self.by_key.values(), SLAVE)

    def target_attributes(self) -> list[AttrR[Any, Any]]:
        """What goes invalid when the target is lost: points, diagnostics and
        CoE values (the slave may come back with other parameters)."""
        diag = [attr for leaf, attr in self.diag.items() if leaf != "Type"]
        return [*self.by_key.values(), *diag, *self.coe_attributes]

    async def refresh_coe(self) -> None:
        """Read every CoE attribute again (SDO uploads): on demand, and after
        the target came back, so the PVs show what the slave holds now."""
        for attr in self.coe_attributes:
            await self.read_coe(attr)

    async def read_coe(self, attr: AttrR[Any, Any]) -> None:
        """One SDO upload posted through `health`: a fresh value ends a
        connection alarm; a failed read of a value in alarm says so (READ)
        instead of the stale reason. Never raises."""
        coe_io, ref = self.coe_io, attr.io_ref
        if coe_io is None or not isinstance(ref, CoeRef):
            return
        coe = ref.coe
        try:
            value = from_device(attr, await coe_io.reader(coe))
        except Exception as error:  # one object must not stop the others
            text = f"{type(error).__name__}: {error}"
            coe_io.failures[coe.attribute] = text
            if self.health.is_invalid(attr):
                self.health.mark_invalid([attr], COE_READ, Status.READ, text)
                await self.health.mark_ok([attr], COMM)
            return
        coe_io.failures.pop(coe.attribute, None)
        try:
            await self.health.post(attr, value)
            await self.health.mark_ok([attr], COE_READ)
        except Exception as error:
            coe_io.failures[coe.attribute] = f"{type(error).__name__}: {error}"


class GenericTerminalController(TerminalController):
    """A terminal with no YAML of its type: whatever symbols discovery found.

    Same attributes and diagnostics as a known terminal; its `Type` reads
    what the master reports (`unknown` if nothing) and its description
    names the identity the master reported.
    """


def _describe(plan: TerminalPlan) -> str:
    slave = plan.slave
    kind = plan.terminal_type or f"unknown {slave.identity}"
    return f"{slave.name}: {kind}"
