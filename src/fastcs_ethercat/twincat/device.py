"""One simulated I/O device: its master, layout, process image, symbol
table, signal generators and symbol handles, kept consistent across online
changes."""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any, Final

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.chain.file import SignalSpec, SystemSpec
from fastcs_ethercat.twincat.generators import (
    Leaf,
    SignalBank,
    default_signal,
    input_leaves,
    leaf_key,
)
from fastcs_ethercat.twincat.image import ProcessImage
from fastcs_ethercat.twincat.itemfaults import FailingBits, error_of, failing_bits
from fastcs_ethercat.twincat.layout import (
    DATAGRAM_IN_OUT,
    DATAGRAM_OUTPUTS,
    DEV_STATE_OFFSET,
    FRM0_INPUT_TOGGLE_OFFSET,
    FRM0_WCSTATE_OFFSET,
    INPUTS,
    SLAVE_COUNT_OFFSET,
    DeviceLayout,
    build_layout,
)
from fastcs_ethercat.twincat.master import EtherCatMaster
from fastcs_ethercat.twincat.resolve import ResolvedMaster, ResolvedSlave
from fastcs_ethercat.twincat.symtab import Resolved, SymbolTable

FIRST_HANDLE: Final = 0x0000_0101
DEV_STATE_LINK_ERROR: Final = 0x0001
FRAME_LOST: Final = 0x0001


@dataclass(frozen=True, slots=True)
class Handle:
    """A handle from 0xF003: what it points at, in which configuration.

    Kept by generation (every online change counts), not by the symbol
    version, which wraps at 255: TwinCAT drops every handle on an online
    change, so one taken 255 changes ago must not come back to life."""

    resolved: Resolved
    generation: int


class SimDevice:
    """Everything behind one device's ports (27904 + id, 0xFFFF, slaves)."""

    def __init__(
        self,
        master: ResolvedMaster,
        *,
        seed: int,
        cycle_s: float,
        system: SystemSpec,
    ) -> None:
        self.master = master
        self.seed = seed
        self.cycle_s = cycle_s
        self.system = system
        """Which services the device port offers (sum write, 0xF008, 0xF00F)."""
        self.ethercat = EtherCatMaster(master)
        self.generation = 0
        self.version = 1
        self.handles: dict[int, Handle] = {}
        self._next_handle = FIRST_HANDLE
        self._pinned: set[str] = set()
        self._toggle = 0
        self.read_errors: dict[str, int] = {}
        """Symbol name -> the ADS error every read of it answers (a fault)."""
        self._build(None)

    @property
    def device_id(self) -> int:
        return self.master.device_id

    @property
    def name(self) -> str:
        return self.master.name

    # -- building -------------------------------------------------------------

    def _build(self, previous: tuple[ProcessImage, SymbolTable] | None) -> None:
        self.layout: DeviceLayout = build_layout(self.master, self.generation)
        self.image = ProcessImage(self.layout.input_size, self.layout.output_size)
        self.table = SymbolTable(self.layout, self.version)
        names = {slave.position: slave.name for slave in self.master.slaves}
        leaves = input_leaves(self.layout.symbols, names)
        specs = [self._spec(leaf) for leaf in leaves]
        keys = [leaf_key(self.seed, self.name, leaf.signal_name) for leaf in leaves]
        self.bank = SignalBank(leaves, specs, keys, self.cycle_s)
        if previous is not None:
            self._carry_values(*previous)
        self.bank.pin(self._pinned)
        self.refresh_states()

    def _spec(self, leaf: Leaf) -> SignalSpec:
        """The chain's generator for a leaf (by symbol, member or element
        name below the terminal, then per terminal), else the default."""
        spec = self.master.slaves[leaf.slave].spec
        for name, chosen in spec.signals.items():
            if _signal_applies(name, leaf):
                return chosen
        if spec.signal is not None:
            return spec.signal
        return default_signal(leaf, self.cycle_s)

    def unmatched_signals(self) -> list[tuple[int, str]]:
        """(slave position, name) of chain `signals` that drive no input."""
        unmatched: list[tuple[int, str]] = []
        for slave in self.master.slaves:
            mine = [leaf for leaf in self.bank.leaves if leaf.slave == slave.position]
            for name in slave.spec.signals:
                if not any(_signal_applies(name, leaf) for leaf in mine):
                    unmatched.append((slave.position, name))
        return unmatched

    def _carry_values(self, image: ProcessImage, table: SymbolTable) -> None:
        """Keep every value whose symbol survives an online change."""
        for old in table.symbols:
            new = self.table.symbol(old.name)
            if new is None or new.type.signature() != old.type.signature():
                continue
            data = image.read_raw(old.area, old.bit_address, old.type)
            self.image.write_raw(new.area, new.bit_address, new.type, data)

    # -- the task cycle -------------------------------------------------------

    def tick(self, cycle: int) -> None:
        """Advance to `cycle`: new inputs for exchanging slaves, runtime values."""
        self.ethercat.cycle()
        self._toggle = cycle & 1
        self.bank.apply(self.image.inputs, cycle)
        self.write_runtime()

    def refresh_states(self) -> None:
        """After a state or link change: who exchanges data, runtime values."""
        live = {rt.slave.position for rt in self.ethercat.slaves if rt.exchanging}
        self.bank.set_live_slaves(live)
        self.write_runtime()

    def write_runtime(self) -> None:
        """WcState / InputToggle bits, the master's Inputs and InfoData."""
        layout = self.layout
        buffer = self.image.inputs
        bad = 0
        has_inputs = 0
        for image, runtime in zip(layout.slaves, self.ethercat.slaves, strict=True):
            if image.datagram is None:
                continue
            needs_op = image.datagram in (DATAGRAM_IN_OUT, DATAGRAM_OUTPUTS)
            ok = not runtime.lost and (
                runtime.al_state == 8 if needs_op else runtime.exchanging
            )
            if not ok:
                bad |= 1 << image.datagram
            if image.has_inputs:
                has_inputs |= 1 << image.datagram
        toggles = (has_inputs & ~bad) if self._toggle else 0
        base = layout.inputs_struct
        link_lost = any(runtime.lost for runtime in self.ethercat.slaves)
        responding = sum(1 for runtime in self.ethercat.slaves if not runtime.lost)
        _put_u16(buffer, base, FRAME_LOST if link_lost else 0)
        _put_u16(buffer, base + FRM0_WCSTATE_OFFSET, bad)
        _put_u16(buffer, base + FRM0_INPUT_TOGGLE_OFFSET, toggles)
        _put_u16(buffer, base + SLAVE_COUNT_OFFSET, responding)
        _put_u16(
            buffer, base + DEV_STATE_OFFSET, DEV_STATE_LINK_ERROR if link_lost else 0
        )
        if layout.info_data:
            netid = self.master.net_id.to_bytes()
            for position, offset in layout.info_data.items():
                runtime = self.ethercat.slaves[position]
                _put_u16(buffer, offset, runtime.state)
                buffer[offset + 2 : offset + 8] = netid
                _put_u16(buffer, offset + 8, runtime.slave.address)

    # -- online change ----------------------------------------------------------

    def online_change(
        self,
        pdo_groups: Mapping[str, str] | None = None,
        removed: Collection[str] = (),
    ) -> None:
        """A new configuration: the symbol version changes, offsets move,
        handles taken before fail with 0x711; values of surviving symbols stay.
        `pdo_groups` (slave name -> group) activates other PDO groups; the
        slaves named in `removed` leave the bus (the others keep their
        addresses, names and states)."""
        if removed:
            self.master = _without(self.master, removed)
            self.ethercat.keep_slaves(self.master)
        if pdo_groups:
            self.master = _with_groups(self.master, pdo_groups)
            self.ethercat.master = self.master
            for runtime, slave in zip(
                self.ethercat.slaves, self.master.slaves, strict=True
            ):
                runtime.slave = slave
        previous = (self.image, self.table)
        self.generation += 1
        self.version = (self.version % 255) + 1
        self._build(previous)

    # -- values by name ----------------------------------------------------------

    def resolve(self, name: str) -> Resolved | None:
        return self.table.resolve(name)

    def get_value(self, name: str) -> Any:
        found = self._require(name)
        return self.image.get_value(found.area, found.bit_address, found.type)

    def set_value(self, name: str, value: Any) -> None:
        """Set a value; an input keeps it (its generator stops)."""
        found = self._require(name)
        self.image.set_value(found.area, found.bit_address, found.type, value)
        if found.area is INPUTS:
            names = {
                leaf.name for leaf in self.bank.leaves if _below(leaf.name, found.name)
            }
            self._pinned |= names
            self.bank.pin(names)

    def unpin_all(self) -> None:
        self._pinned.clear()
        self.bank.unpin_all()

    def _require(self, name: str) -> Resolved:
        found = self.table.resolve(name)
        if found is None:
            raise KeyError(f"{self.name} has no symbol {name!r}")
        return found

    # -- handles ------------------------------------------------------------------

    def new_handle(self, resolved: Resolved) -> int:
        handle = self._next_handle
        self._next_handle += 1
        self.handles[handle] = Handle(resolved, self.generation)
        return handle

    def handle(self, handle: int) -> tuple[int, Resolved | None]:
        """(result, what it points at): 0x710 unknown, 0x711 outdated."""
        found = self.handles.get(handle)
        if found is None:
            return AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND, None
        if found.generation != self.generation:
            return AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID, None
        return AdsReturnCode.NO_ERROR, found.resolved

    def release_handle(self, handle: int) -> int:
        if self.handles.pop(handle, None) is None:
            return AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
        return AdsReturnCode.NO_ERROR

    # -- per-symbol read errors ------------------------------------------------

    def fail_reads(self, name: str, code: int) -> None:
        """Every read touching symbol `name` answers `code` (until cleared)."""
        self._require(name)
        self.read_errors[name] = code

    def failing(self) -> list[FailingBits]:
        """Where the symbols of `read_errors` are in the current layout."""
        return failing_bits(self.table, self.read_errors) if self.read_errors else []

    def read_resolved(self, found: Resolved, length: int) -> tuple[int, bytes]:
        """The value's bytes; a shorter read gets its first bytes (pyads
        users read one character of a STRING or the first elements of an
        array that way), a longer one the whole value."""
        if self.read_errors:
            bits = FailingBits.of(found, 0)
            code = error_of(self.failing(), bits.area, bits.first, bits.end)
            if code:
                return code, b""
        data = self.image.read_raw(found.area, found.bit_address, found.type)
        return AdsReturnCode.NO_ERROR, data[:length]

    def write_resolved(self, found: Resolved, data: bytes) -> int:
        if len(data) != found.size:
            return AdsReturnCode.DEVICE_INVALID_SIZE
        try:
            self.image.write_raw(found.area, found.bit_address, found.type, data)
        except AdsCodecError as error:
            return error.return_code
        return AdsReturnCode.NO_ERROR

    def slave(self, address_or_name: int | str) -> ResolvedSlave | None:
        for slave in self.master.slaves:
            if address_or_name in (slave.address, slave.name):
                return slave
        return None


def _signal_applies(name: str, leaf: Leaf) -> bool:
    """A `signals` key names the leaf, a structure or array above it, or the
    entry path of a one-entry PDO (`Channel 1.Input` for `Channel 1`)."""
    key, folded = name.casefold(), leaf.relative.casefold()
    if folded == key or folded.startswith((f"{key}.", f"{key}[")):
        return True
    return (
        leaf.top_level
        and key.startswith(f"{folded}.")
        and "." not in key[len(folded) + 1 :]
    )


def _put_u16(buffer: bytearray, offset: int, value: int) -> None:
    buffer[offset : offset + 2] = (value & 0xFFFF).to_bytes(2, "little")


def _below(leaf: str, name: str) -> bool:
    folded, key = leaf.casefold(), name.casefold()
    return folded == key or folded.startswith((f"{key}.", f"{key}["))


def _without(master: ResolvedMaster, removed: Collection[str]) -> ResolvedMaster:
    """`master` without the slaves named in `removed`, the rest moved up."""
    kept = [slave for slave in master.slaves if slave.name not in removed]
    return dataclasses.replace(
        master,
        slaves=tuple(
            dataclasses.replace(slave, position=position)
            for position, slave in enumerate(kept)
        ),
    )


def _with_groups(
    master: ResolvedMaster, pdo_groups: Mapping[str, str]
) -> ResolvedMaster:
    slaves = []
    known = {slave.name for slave in master.slaves}
    for name in pdo_groups:
        if name not in known:
            raise KeyError(f"{master.name} has no slave {name!r}")
    for slave in master.slaves:
        group = pdo_groups.get(slave.name)
        if group is None:
            slaves.append(slave)
            continue
        names = [g.name for g in slave.terminal.pdo_groups]
        if group not in names:
            raise ValueError(f"{slave.type_name} has no PDO group {group!r} ({names})")
        terminal = slave.terminal.model_copy(update={"selected_pdo_group": group})
        oversampling = terminal.oversampling
        chosen = terminal.active_group
        if oversampling is not None and oversampling.by_group and chosen is not None:
            factor = chosen.oversampling_factor or oversampling.selected_factor
            terminal = terminal.model_copy(
                update={
                    "oversampling": oversampling.model_copy(
                        update={"selected_factor": factor}
                    )
                }
            )
        slaves.append(dataclasses.replace(slave, terminal=terminal))
    return dataclasses.replace(master, slaves=tuple(slaves))


__all__ = ["Handle", "SimDevice"]
