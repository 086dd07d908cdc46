"""`SimTarget`: a whole simulated TwinCAT system behind one `handle(packet)`.

The I/O layer (server, notifications, control API) feeds it decoded AMS
packets and sends back what it returns; it never blocks and never touches a
socket. See `sim/__init__.py` for the interface and the behaviour.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from fastcs_ethercat.ads import commands
from fastcs_ethercat.ads.commands import AdsRequest, error_packet
from fastcs_ethercat.ads.constants import (
    AdsReturnCode,
    AmsCommand,
    AmsPort,
    IndexGroup,
    device_port,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.ethercat import AlState
from fastcs_ethercat.ads.frames import AmsPacket
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.chain.file import Chain, SystemSpec, load_chain
from fastcs_ethercat.shipped import BUILTIN_TERMINALS_DIR
from fastcs_ethercat.terminals.registry import TerminalRegistry
from fastcs_ethercat.twincat.device import SimDevice
from fastcs_ethercat.twincat.resolve import (
    ResolvedSlave,
    Revisions,
    chain_registry,
    registry_for,
    resolve_chain,
    revisions_of,
)
from fastcs_ethercat.twincat.services import (
    DEVICE_PORT_NAME,
    IO_SERVER_NAME,
    MASTER_PORT_NAME,
    SYSTEM_SERVICE_NAME,
    DevicePort,
    IoServerPort,
    MasterPort,
    Port,
    RunState,
    SlavePort,
    SystemServicePort,
)

_GROUP_COMMANDS: Final = (
    commands.ReadRequest,
    commands.WriteRequest,
    commands.ReadWriteRequest,
)
_AL_STATES: Final = {state.name: int(state) for state in AlState}
_SUM_GROUPS: Final = frozenset(
    {IndexGroup.SUMUP_READ, IndexGroup.SUMUP_WRITE, IndexGroup.SUMUP_READ_WRITE}
)


class SimTarget:
    """A TwinCAT system: I/O server, EtherCAT masters, devices and slaves."""

    def __init__(
        self,
        chain: Chain,
        terminals: TerminalRegistry | Path | str,
        seed: int = 0,
        revisions: Revisions | None = None,
    ) -> None:
        self.chain = chain
        self.seed = seed
        system: SystemSpec = chain.system
        self.system_net_id, masters = resolve_chain(chain, terminals, revisions)
        self.notes = [s.note for m in masters for s in m.slaves if s.note]
        """Slaves played from the YAML of another revision than they report."""
        self.cycle_s = system.task_cycle_ms / 1000.0
        self.run = RunState()
        self.devices = [
            SimDevice(
                master,
                seed=seed,
                cycle_s=self.cycle_s,
                system=system,
            )
            for master in masters
        ]
        self._check_signals()
        self.net_ids: set[AmsNetId] = {self.system_net_id}
        self.net_ids.update(device.master.net_id for device in self.devices)
        self._ports: dict[AmsAddress, Port] = {}
        self._route()
        self._forced: tuple[int, int | None] | None = None
        self.sum_commands = True
        """False: 0xF080-0xF082 answered 0x701 (fault `no_sum_commands`)."""
        self._start: float | None = None
        self._cycle = -1

    @classmethod
    def from_chain(
        cls,
        chain: Chain | Path | str,
        terminals_dir: TerminalRegistry | Path | str | None = None,
        seed: int = 0,
        revisions: Revisions | None = None,
    ) -> SimTarget:
        """Build from a chain (or a chain file) and the terminal YAML directory
        (default: the chain's own `terminal_dirs`, every revision in them
        played as its own, else the shipped types), with YAML of other
        revisions (`load_revisions`)."""
        if not isinstance(chain, Chain):
            chain = load_chain(chain)
        own = chain_registry(chain) if terminals_dir is None else None
        if own is not None:
            return cls(chain, own, seed, {**revisions_of(own), **(revisions or {})})
        terminals = (
            terminals_dir
            if isinstance(terminals_dir, TerminalRegistry)
            else registry_for(
                BUILTIN_TERMINALS_DIR if terminals_dir is None else terminals_dir,
                {slave.type for master in chain.masters for slave in master.slaves},
            )
        )
        return cls(chain, terminals, seed, revisions)

    def _check_signals(self) -> None:
        """A `signals` name that drives nothing is a typo: say where."""
        for m, device in enumerate(self.devices):
            for position, name in device.unmatched_signals():
                slave = device.master.slaves[position]
                raise self.chain.error(
                    ("masters", m, "slaves", position, "signals", name),
                    f"{slave.name} has no input symbol or member {name!r}",
                )

    def _route(self) -> None:
        system = self.system_net_id
        ports: dict[AmsAddress, Port] = {
            AmsAddress(system, AmsPort.IO_SERVER): IoServerPort(
                self.run, IO_SERVER_NAME, list(self.devices)
            ),
            AmsAddress(system, AmsPort.SYSTEM_SERVICE): SystemServicePort(
                self.run, SYSTEM_SERVICE_NAME
            ),
        }
        for device in self.devices:
            ports[AmsAddress(system, device_port(device.device_id))] = DevicePort(
                self.run, DEVICE_PORT_NAME, device
            )
            net_id = device.master.net_id
            ports[AmsAddress(net_id, AmsPort.ETHERCAT_MASTER)] = MasterPort(
                self.run, MASTER_PORT_NAME, device
            )
            for runtime in device.ethercat.slaves:
                ports[AmsAddress(net_id, runtime.slave.address)] = SlavePort(
                    self.run, runtime.slave.type_name, device, runtime
                )
        self._ports = ports

    # -- the ADS entry points -------------------------------------------------

    def handle(self, packet: AmsPacket) -> AmsPacket | None:
        """The response to one request (None for packets that get none)."""
        if packet.is_response or packet.command == AmsCommand.DEVICE_NOTIFICATION:
            return None
        if packet.target.netid not in self.net_ids:
            return packet.response(error_code=AdsReturnCode.TARGET_MACHINE_NOT_FOUND)
        port = self._ports.get(packet.target)
        if port is None:
            return packet.response(error_code=AdsReturnCode.TARGET_PORT_NOT_FOUND)
        command = int(packet.command)
        try:
            request = commands.decode_request(command, packet.payload)
        except AdsCodecError as error:
            return error_packet(packet, error.return_code)
        forced = self._forced_error(request)
        if forced:
            return error_packet(packet, forced)
        return packet.response(payload=self._serve(port, request).encode())

    def read(
        self, address: AmsAddress, group: int, offset: int, length: int
    ) -> tuple[int, bytes]:
        """(result, data) of a Read, for notifications sampled by the I/O layer."""
        port = self._ports.get(address)
        if port is None:
            return AdsReturnCode.TARGET_PORT_NOT_FOUND, b""
        if self._forced is not None and self._forced[1] in (None, group):
            return self._forced[0], b""
        return port.read(group, offset, length)

    def _forced_error(self, request: AdsRequest) -> int:
        if (
            not self.sum_commands
            and isinstance(request, commands.ReadWriteRequest)
            and request.index_group in _SUM_GROUPS
        ):
            return AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
        if self._forced is None:
            return 0
        code, group = self._forced
        if group is None:
            return code
        if isinstance(request, _GROUP_COMMANDS) and request.index_group == group:
            return code
        return 0

    def _serve(self, port: Port, request: AdsRequest) -> Any:
        if isinstance(request, commands.ReadRequest):
            result, data = port.read(
                request.index_group, request.index_offset, request.length
            )
            return commands.ReadResponse(result, data if result == 0 else b"")
        if isinstance(request, commands.WriteRequest):
            return commands.WriteResponse(
                port.write(
                    request.index_group, request.index_offset, bytes(request.data)
                )
            )
        if isinstance(request, commands.ReadWriteRequest):
            result, data = port.read_write(
                request.index_group,
                request.index_offset,
                request.read_length,
                bytes(request.data),
            )
            return commands.ReadWriteResponse(result, data if result == 0 else b"")
        if isinstance(request, commands.ReadStateRequest):
            ads_state, device_state = port.read_state()
            return commands.ReadStateResponse(
                AdsReturnCode.NO_ERROR, ads_state, device_state
            )
        if isinstance(request, commands.ReadDeviceInfoRequest):
            return port.device_info()
        if isinstance(request, commands.WriteControlRequest):
            return commands.WriteControlResponse(
                port.write_control(
                    request.ads_state, request.device_state, request.data
                )
            )
        # Notifications are the I/O layer's; nothing else reaches a port.
        return commands.error_response(
            int(request.command), AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
        )

    # -- the task cycle --------------------------------------------------------

    def tick(self, now: float) -> None:
        """Advance the I/O task to `now` (seconds, monotonic): inputs of every
        exchanging slave move to the values of the current cycle."""
        if self._start is None:
            self._start = now
        if not self.run.running:
            return
        cycle = math.floor((now - self._start) / self.cycle_s + 1e-9)
        if cycle <= self._cycle:
            return
        self._cycle = cycle
        for device in self.devices:
            device.tick(cycle)

    @property
    def cycle(self) -> int:
        """The task cycle the inputs show (0 before the first tick)."""
        return max(self._cycle, 0)

    # -- faults and control ----------------------------------------------------

    def set_slave_state(
        self,
        address_or_name: int | str | None,
        state: int | str,
        device: int | None = None,
    ) -> None:
        """Put one slave (by EtherCAT address or TwinCAT name; None: every
        slave) into INIT, PREOP, BOOT, SAFEOP or OP (or a raw state byte)."""
        value = _AL_STATES[state.upper()] if isinstance(state, str) else int(state)
        for owner, slave in self._select(address_or_name, device):
            runtime = owner.ethercat.slaves[slave.position]
            runtime.state = value
            owner.refresh_states()

    def set_link_lost(
        self, address_or_name: int | str | None, lost: bool, device: int | None = None
    ) -> None:
        """Lose (or restore) one slave's link (None: every slave)."""
        for owner, slave in self._select(address_or_name, device):
            owner.ethercat.slaves[slave.position].lost = lost
            owner.refresh_states()

    def online_change(
        self,
        pdo_groups: Mapping[str, str] | None = None,
        removed: Sequence[str] = (),
    ) -> None:
        """Activate a new configuration on every device: symbol version +1,
        offsets move, old handles answer 0x711. `pdo_groups` (slave name ->
        group) switches PDO groups at the same time; the slaves named in
        `removed` leave the configuration (a terminal taken off the rack)."""
        remaining = dict(pdo_groups or {})
        leaving = set(removed)
        for device in self.devices:
            mine = {
                name: group
                for name, group in remaining.items()
                if device.slave(name) is not None
            }
            gone = {name for name in leaving if device.slave(name) is not None}
            for name in mine:
                remaining.pop(name)
            leaving -= gone
            device.online_change(mine, gone)
        if remaining or leaving:
            raise KeyError(f"no slaves called {sorted({*remaining, *leaving})}")
        self._route()

    def set_run_state(self, running: bool) -> None:
        """RUN (ReadState 5, inputs move) or STOP (ReadState 6, frozen)."""
        self.run.running = running
        for device in self.devices:
            device.ethercat.running = running

    def force_error(self, code: int, group: int | None = None) -> None:
        """Answer every request (or those for one index group) with `code`."""
        self._forced = (int(code), group)

    def set_sum_commands(self, served: bool) -> None:
        """Serve sum commands (0xF080-0xF082), or answer them 0x701."""
        self.sum_commands = served

    def fail_symbols(self, code: int, symbols: Sequence[str]) -> None:
        """Every read touching one of `symbols` answers `code` (per item in a
        sum read); unknown names raise KeyError and change nothing."""
        owners = [(self._device_of(name, None), name) for name in symbols]
        for device, name in owners:
            device.fail_reads(name, int(code))

    def clear_faults(self) -> None:
        """Back to normal: no forced error, running, slaves in their chain
        states with links up, every input driven by its generator again."""
        self._forced = None
        self.sum_commands = True
        for device in self.devices:
            device.read_errors.clear()
        self.set_run_state(True)
        for device in self.devices:
            device.ethercat.reset()
            device.unpin_all()
            device.refresh_states()

    def get_symbol_value(self, name: str, device: int | None = None) -> Any:
        """A value by TwinCAT symbol name (members and elements too)."""
        return self._device_of(name, device).get_value(name)

    def set_symbol_value(
        self, name: str, value: Any, device: int | None = None
    ) -> None:
        """Set a value by name; an input keeps it until `clear_faults`."""
        self._device_of(name, device).set_value(name, value)

    def describe(self) -> dict[str, Any]:
        """What the simulator plays, for a ready line and the control API."""
        masters = [
            {
                "name": device.name,
                "device_id": device.device_id,
                "net_id": str(device.master.net_id),
                "ads_port": device_port(device.device_id),
                "slaves": len(device.master.slaves),
                "symbols": len(device.table),
                "symbol_version": device.version,
            }
            for device in self.devices
        ]
        return {
            "net_id": str(self.system_net_id),
            "masters": masters,
            "slaves": sum(m["slaves"] for m in masters),
            "symbols": sum(m["symbols"] for m in masters),
            "running": self.run.running,
            "cycle": self.cycle,
        }

    # -- helpers -------------------------------------------------------------------

    def _select(
        self, address_or_name: int | str | None, device: int | None
    ) -> list[tuple[SimDevice, ResolvedSlave]]:
        chosen = [d for d in self.devices if device is None or d.device_id == device]
        if device is not None and not chosen:
            raise KeyError(f"no device {device}")
        if address_or_name is None:
            return [(d, s) for d in chosen for s in d.master.slaves]
        for owner in chosen:
            slave = owner.slave(address_or_name)
            if slave is not None:
                return [(owner, slave)]
        raise KeyError(f"no slave {address_or_name!r}")

    def _device_of(self, name: str, device: int | None) -> SimDevice:
        chosen = [d for d in self.devices if device is None or d.device_id == device]
        for owner in chosen:
            if owner.resolve(name) is not None:
                return owner
        raise KeyError(f"no symbol {name!r}")

    @property
    def addresses(self) -> Collection[AmsAddress]:
        """Every AMS address that answers (the rest answer AMS error 0x6)."""
        return self._ports.keys()


__all__ = ["SimTarget"]
