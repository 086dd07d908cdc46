"""The EtherCAT master of one I/O device: slave states, link, counters, and
its answers on port 0xFFFF of the device NetId (facts section 6).

Groups (index offset in brackets): 0x03 [0x100] master state u16, written
with the requested state as offset to request it (Beckhoff "ADS Interface"
of the EtherCAT device); 0x06 slave
count u16; 0x07 slave addresses u16 x n; 0x09 [0] (AL state, link) per
slave, [address] one slave; 0x0C frame counters 5 x u32; 0x11 [address]
identity 4 x u32; 0x12 [address] CRC counters 4 x u32, [0] one u32 per
slave (its ports added); 0xF302 the master's
CoE (0x1018 identity, 0x8000 + n sub 2 / 3: type and name of slave n).
"""

from __future__ import annotations

from dataclasses import astuple, dataclass, field
from typing import Final

from fastcs_ethercat.ads.constants import (
    MASTER_STATE_OFFSET,
    AdsReturnCode,
    EtherCatMasterGroup,
    IndexGroup,
)
from fastcs_ethercat.ads.ethercat import (
    SLAVE_INFO_INDEX,
    SLAVE_NAME_SUBINDEX,
    SLAVE_TYPE_SUBINDEX,
    AlState,
    CrcCounters,
    FrameCounters,
    LinkState,
    SlaveIdentity,
    SlaveState,
    encode_crc_totals,
    encode_master_state,
    encode_slave_addresses,
    encode_slave_count,
    encode_slave_states,
)
from fastcs_ethercat.ads.wire import encode_text
from fastcs_ethercat.twincat.answers import fit
from fastcs_ethercat.twincat.coe import IDENTITY_INDEX, CoeDictionary, split_offset
from fastcs_ethercat.twincat.resolve import ResolvedMaster, ResolvedSlave

MASTER_IDENTITY: Final = SlaveIdentity(
    vendor_id=2, product_code=0x00010003, revision=1844
)
"""What the master's CoE 0x1018 reports (a real CX's EtherCAT device, catio dump)."""
LOST: Final = LinkState.NOT_PRESENT
"""Link state of a slave the master cannot reach (EC_LINK_STATE_NOT_PRESENT)."""
NEIGHBOUR_LOST: Final = LinkState.MISSING_LINK | LinkState.PORT_B
"""Link state of the slave before it: no link on its outgoing port (B)."""
DATA_STATES: Final = frozenset({AlState.SAFEOP, AlState.OP})
"""States in which a slave's inputs are exchanged."""


@dataclass(slots=True)
class SlaveRuntime:
    """What changes about one slave while the simulator runs."""

    slave: ResolvedSlave
    state: int
    lost: bool = False
    """The master cannot reach it (cable, power): see `EtherCatMaster.link`."""
    crc: list[int] = field(default_factory=lambda: [0, 0, 0, 0])
    coe: CoeDictionary = field(default_factory=lambda: CoeDictionary(()))

    @property
    def al_state(self) -> int:
        return self.state & 0x0F

    @property
    def exchanging(self) -> bool:
        """Inputs move only in SAFEOP / OP with the link up."""
        return self.al_state in DATA_STATES and not self.lost

    @property
    def mailbox_ready(self) -> bool:
        """CoE needs PREOP or higher and a link."""
        return self.al_state >= AlState.PREOP and not self.lost


class EtherCatMaster:
    """One master's slaves and counters, and its ADS answers."""

    def __init__(self, master: ResolvedMaster) -> None:
        self.master = master
        self.slaves = [self._runtime(slave) for slave in master.slaves]
        self.by_address = {rt.slave.address: rt for rt in self.slaves}
        self.cycles = 0
        self.lost_frames = 0
        self.acyclic_frames = 0
        self.running = True
        self.requested_state = int(AlState.OP)

    def keep_slaves(self, master: ResolvedMaster) -> None:
        """Follow a new configuration of fewer slaves (`master`'s, found by
        name): the runtimes of those kept keep their states and counters."""
        by_name = {runtime.slave.name: runtime for runtime in self.slaves}
        self.master = master
        self.slaves = []
        for slave in master.slaves:
            runtime = by_name[slave.name]
            runtime.slave = slave
            self.slaves.append(runtime)
        self.by_address = {rt.slave.address: rt for rt in self.slaves}

    @staticmethod
    def _runtime(slave: ResolvedSlave) -> SlaveRuntime:
        coe = CoeDictionary.from_terminal(slave.terminal.coe_objects)
        if len(coe):
            coe.set_identity(slave.identity)
        return SlaveRuntime(slave=slave, state=int(slave.initial_state), coe=coe)

    # -- state changes -------------------------------------------------------

    def reset(self) -> None:
        """Every slave back to its chain state, links up."""
        self.requested_state = int(AlState.OP)
        for runtime in self.slaves:
            runtime.state = int(runtime.slave.initial_state)
            runtime.lost = False

    def cycle(self) -> None:
        """One task cycle: count frames (lost while a link is down)."""
        self.cycles += 1
        if any(runtime.lost for runtime in self.slaves):
            self.lost_frames += 1

    def request_state(self, state: int) -> int:
        """The master and every slave it reaches go to `state`."""
        if state not in {int(s) for s in AlState}:
            return AdsReturnCode.DEVICE_INVALID_OFFSET
        self.requested_state = state
        for runtime in self.slaves:
            if not runtime.lost:
                runtime.state = state
        return AdsReturnCode.NO_ERROR

    def link(self, runtime: SlaveRuntime) -> int:
        """The link-state byte: NOT_PRESENT for a lost slave, MISSING_LINK on
        port B for the slave before it (Beckhoff ST_EcSlaveState)."""
        if runtime.lost:
            return int(LOST)
        position = runtime.slave.position
        following = (
            self.slaves[position + 1] if position + 1 < len(self.slaves) else None
        )
        return int(NEIGHBOUR_LOST) if following is not None and following.lost else 0

    def master_state(self) -> int:
        return self.requested_state if self.running else int(AlState.INIT)

    # -- ADS on port 0xFFFF ------------------------------------------------------

    def read(self, group: int, offset: int, length: int) -> tuple[int, bytes]:
        if group == IndexGroup.COE_SDO:
            return self._coe_read(offset, length)
        data = self._query(group, offset)
        if isinstance(data, int):
            return data, b""
        return fit(data, length)

    def write(self, group: int, offset: int, data: bytes) -> int:
        if group == EtherCatMasterGroup.MASTER_STATE:
            return self.request_state(offset)
        if group == IndexGroup.COE_SDO:
            return AdsReturnCode.DEVICE_INVALID_ACCESS
        if group in _KNOWN_GROUPS:
            return AdsReturnCode.DEVICE_INVALID_ACCESS
        return AdsReturnCode.DEVICE_INVALID_GROUP

    def _query(self, group: int, offset: int) -> bytes | int:
        match group:
            case EtherCatMasterGroup.MASTER_STATE:
                if offset != MASTER_STATE_OFFSET:
                    return AdsReturnCode.DEVICE_INVALID_OFFSET
                return encode_master_state(self.master_state())
            case EtherCatMasterGroup.SLAVE_COUNT:
                return encode_slave_count(len(self.slaves))
            case EtherCatMasterGroup.SLAVE_ADDRESSES:
                return encode_slave_addresses([rt.slave.address for rt in self.slaves])
            case EtherCatMasterGroup.SLAVE_STATES:
                if offset == 0:
                    return encode_slave_states(
                        [SlaveState(rt.state, self.link(rt)) for rt in self.slaves]
                    )
                runtime = self.by_address.get(offset)
                if runtime is None:
                    return AdsReturnCode.DEVICE_INVALID_OFFSET
                return SlaveState(runtime.state, self.link(runtime)).encode()
            case EtherCatMasterGroup.FRAME_COUNTERS:
                return FrameCounters(
                    time=self.cycles,
                    cyclic_sent=self.cycles,
                    cyclic_lost=self.lost_frames,
                    acyclic_sent=self.acyclic_frames,
                    acyclic_lost=0,
                ).encode()
            case EtherCatMasterGroup.SLAVE_IDENTITY:
                runtime = self.by_address.get(offset)
                if runtime is None:
                    return AdsReturnCode.DEVICE_INVALID_OFFSET
                return runtime.slave.identity.encode()
            case EtherCatMasterGroup.SLAVE_CRC_COUNTERS:
                if offset == 0:  # every slave at once (catio reads this)
                    return encode_crc_totals(
                        [CrcCounters(*rt.crc).total for rt in self.slaves]
                    )
                runtime = self.by_address.get(offset)
                if runtime is None:
                    return AdsReturnCode.DEVICE_INVALID_OFFSET
                return CrcCounters(*runtime.crc).encode()
        return AdsReturnCode.DEVICE_INVALID_GROUP

    def _coe_read(self, offset: int, length: int) -> tuple[int, bytes]:
        """The master's own small dictionary (identity, slave types/names)."""
        index, subindex, _ = split_offset(offset)
        data: bytes | None = None
        if index == IDENTITY_INDEX and 1 <= subindex <= 4:
            data = astuple(MASTER_IDENTITY)[subindex - 1].to_bytes(4, "little")
        elif SLAVE_INFO_INDEX <= index < SLAVE_INFO_INDEX + len(self.slaves):
            slave = self.slaves[index - SLAVE_INFO_INDEX].slave
            if subindex == SLAVE_TYPE_SUBINDEX:
                data = encode_text(slave.type_name)
            elif subindex == SLAVE_NAME_SUBINDEX:
                data = encode_text(slave.name)
        if data is None:
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        return fit(data, length)

    # -- ADS on a slave's port (mailbox) ------------------------------------------

    def slave_read(
        self, runtime: SlaveRuntime, group: int, offset: int, length: int
    ) -> tuple[int, bytes]:
        if group != IndexGroup.COE_SDO:
            return AdsReturnCode.DEVICE_INVALID_GROUP, b""
        refused = self._mailbox_refusal(runtime)
        if refused:
            return refused, b""
        self.acyclic_frames += 1
        return runtime.coe.read(offset, length)

    def slave_write(
        self, runtime: SlaveRuntime, group: int, offset: int, data: bytes
    ) -> int:
        if group != IndexGroup.COE_SDO:
            return AdsReturnCode.DEVICE_INVALID_GROUP
        refused = self._mailbox_refusal(runtime)
        if refused:
            return refused
        self.acyclic_frames += 1
        return runtime.coe.write(offset, data)

    @staticmethod
    def _mailbox_refusal(runtime: SlaveRuntime) -> int:
        if not len(runtime.coe):
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
        if runtime.lost:
            return AdsReturnCode.DEVICE_TIMEOUT
        if not runtime.mailbox_ready:
            return AdsReturnCode.DEVICE_NOT_READY
        return AdsReturnCode.NO_ERROR


_KNOWN_GROUPS: Final = frozenset(int(group) for group in EtherCatMasterGroup)


__all__ = ["EtherCatMaster", "SlaveRuntime"]
