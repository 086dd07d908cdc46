"""One controller per EtherCAT master: state, slave count, frame counters.

The master's own queries (port 0xFFFF of the device's NetId) are slow-moving
diagnostics, read once a second in one scan that also hands every slave its
AL state, link state and CRC errors. Any failure is counted and shown, never
raised: an exception out of a scan would pause every scan of the tree.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Final

from fastcs.attributes import AttrR
from fastcs.controllers import Controller
from fastcs.datatypes import Bool, Int, String
from fastcs.methods import scan

from fastcs_ethercat.ads.constants import MASTER_STATE_OFFSET, EtherCatMasterGroup
from fastcs_ethercat.ads.ethercat import (
    CrcCounters,
    FrameCounters,
    SlaveState,
    decode_master_state,
    decode_slave_count,
    decode_slave_states,
)
from fastcs_ethercat.ioc.attributes import (
    PointIO,
    attribute_for_point,
    from_device,
)
from fastcs_ethercat.ioc.controllers.post import post
from fastcs_ethercat.ioc.controllers.terminal import TerminalController
from fastcs_ethercat.ioc.datatypes import IntegralFloat
from fastcs_ethercat.ioc.health import Health
from fastcs_ethercat.ioc.plan import MasterPlan, Point

DIAGNOSTICS_PERIOD_S: Final = 1.0
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


class MasterAds:
    """Reads a master's diagnostics with an `AdsClient` to `<netid>:0xFFFF`."""

    def __init__(self, client: Any, addresses: list[int]) -> None:
        self.client = client
        self.addresses = addresses
        self.reads = 0

    async def __call__(self) -> MasterStatus:
        group = EtherCatMasterGroup
        state = decode_master_state(
            await self.client.read(group.MASTER_STATE, MASTER_STATE_OFFSET, 2)
        )
        count = decode_slave_count(await self.client.read(group.SLAVE_COUNT, 0, 2))
        frames = FrameCounters.decode(
            await self.client.read(group.FRAME_COUNTERS, 0, 20)
        )
        states = decode_slave_states(
            await self.client.read(group.SLAVE_STATES, 0, 2 * count)
        )
        crc: dict[int, int] = {}
        if self.reads % CRC_EVERY == 0:
            crc = await self._crc_counters()
        self.reads += 1
        return MasterStatus(state, count, frames, states, crc)

    async def _crc_counters(self) -> dict[int, int]:
        """Every slave's CRC errors (all ports); one read each, as the master
        answers no sum reads. A slave that does not answer is left out."""
        crc: dict[int, int] = {}
        for address in self.addresses:
            try:
                raw = await self.client.read(
                    EtherCatMasterGroup.SLAVE_CRC_COUNTERS, address, 16
                )
            except Exception:
                continue
            counters = CrcCounters.decode(raw)
            crc[address] = (
                counters.port_a + counters.port_b + counters.port_c + counters.port_d
            )
        return crc


class MasterController(Controller):
    """An EtherCAT master: its counters, and the terminals below it."""

    def __init__(
        self,
        plan: MasterPlan,
        leaves: Mapping[str, str],
        point_io: PointIO,
        reader: MasterReader | None,
        *,
        read_only: bool = False,
        health: Health | None = None,
    ) -> None:
        super().__init__(description=plan.name, ios=[point_io])
        self.plan = plan
        self.health = health or Health()
        self.reader = reader
        self.terminals: dict[int, TerminalController] = {}
        """Every terminal (and coupler) controller below, by slave address."""
        self.terminal_positions: dict[int, int] = {
            t.slave.address: t.slave.position for t in plan.terminals
        }
        self.by_key: dict[str, AttrR[Any, Any]] = {}
        self.unserved: list[tuple[str, str]] = []
        self.failures = 0
        self.last_error = ""
        attrs: dict[str, AttrR[Any, Any]] = {
            "NetId": AttrR(
                String(), initial_value=plan.net_id, description="Master's AMS NetId"
            ),
            "State": AttrR(Int(), description="EtherCAT master state"),
            "SlaveCount": AttrR(Int(), description="Slaves the master sees"),
            "ExpectedSlaves": AttrR(
                Int(),
                initial_value=len(plan.terminals),
                description="Slaves found at start",
            ),
            "Online": AttrR(Bool(), description="Master diagnostics answer"),
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
            self.by_key[point.key] = attr

    async def apply_change(
        self, point: Point, value: Any, stamp: float | None = None
    ) -> None:
        attr = self.by_key.get(point.key)
        if attr is None:
            return
        try:
            await self.health.post(attr, from_device(attr, value), stamp)
        except Exception:  # one value must not stop the scan
            self.failures += 1

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
        await post(a["Online"], True)
        await fresh(a["State"], status.state)
        await fresh(a["SlaveCount"], status.slave_count)
        await fresh(a["CyclicFrames"], frames.cyclic_sent)
        await fresh(a["CyclicLost"], frames.cyclic_lost)
        await fresh(a["AcyclicFrames"], frames.acyclic_sent)
        await fresh(a["AcyclicLost"], frames.acyclic_lost)
        await fresh(a["LostFrames"], frames.cyclic_lost + frames.acyclic_lost)
        await post(a["DiagErrors"], min(self.failures, 2**31 - 1))
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
        """What goes invalid when the target is lost (not what the IOC knows)."""
        own = {"NetId", "ExpectedSlaves", "Online", "DiagErrors"}
        diag = [attr for leaf, attr in self.attrs.items() if leaf not in own]
        return [*self.by_key.values(), *diag]

    async def _safe_post(self, leaf: str, value: Any) -> None:
        try:
            await post(self.attrs[leaf], value)
        except Exception:
            self.failures += 1
