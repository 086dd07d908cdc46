"""Where every symbol of one EtherCAT device lives in its process image.

Evidence (symbol dump of a real 105-terminal rack, catio `hardware-output.txy`;
facts section 7):

- On the device port the terminal inputs are in group 0xF030 (bytes) /
  0xF031 (bits), the outputs in 0xF020 / 0xF021. (The groups are named
  "input"/"output" image from the PLC's side; the device serves them the
  other way round.)
- Byte-sized PDOs are packed without alignment (EL1502 `CNT Inputs` at odd
  offsets, 6 bytes apart), in bus order; single-bit PDOs (EL1014 `Channel 1`)
  follow packed bit after bit in bus order.
- The master's `Inputs` (Frm0State, Frm0WcState, Frm0InputToggle at +0/+2/+4,
  SlaveCount +10, DevState +14) and `Outputs` (Frm0Ctrl, Frm0WcCtrl, DevCtrl)
  come after the terminals' data.
- A terminal's `WcState.WcState` is a bit of `Frm0WcState` and
  `WcState.InputToggle` a bit of `Frm0InputToggle`: one bit per datagram,
  shared by every terminal in it. Terminals with inputs and outputs use bit
  1 (LRW), outputs-only bit 2 (LWR), inputs-only bit 3 (LRD).
- `SyncUnits._default_._unreferenced_.WcState.WcState` is a bit at Inputs+6.

Exact offsets of a real TwinCAT differ (its logical address map has gaps);
what is kept is the grouping, packing and order.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from fastcs_ethercat.ads.constants import AdsDataType, IndexGroup, SymbolFlag
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.symbols import AdsSymbolEntry
from fastcs_ethercat.ads.wire import STRING_ENCODING
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.symbols import ExpandedSymbol
from fastcs_ethercat.twincat.resolve import ResolvedMaster, ResolvedSlave
from fastcs_ethercat.twincat.tctypes import (
    EntrySpec,
    TcMember,
    TcType,
    TypeNamer,
    array_of,
    pdo_type,
    scalar_type,
    structure,
)

GENERATION_SHIFT_BYTES: Final = 16
"""How far an online change moves every offset (per change)."""

DATAGRAM_IN_OUT: Final = 1
DATAGRAM_OUTPUTS: Final = 2
DATAGRAM_INPUTS: Final = 3

INPUTS_STRUCT_SIZE: Final = 16
OUTPUTS_STRUCT_SIZE: Final = 6
FRM0_WCSTATE_OFFSET: Final = 2
FRM0_INPUT_TOGGLE_OFFSET: Final = 4
SYNC_UNIT_OFFSET: Final = 6
SLAVE_COUNT_OFFSET: Final = 10
DEV_STATE_OFFSET: Final = 14
SYNC_UNIT_SYMBOL: Final = "SyncUnits._default_._unreferenced_.WcState.WcState"


@dataclass(frozen=True, slots=True)
class ImageArea:
    """One process image of a device and the groups that address it."""

    name: str
    byte_group: int
    bit_group: int
    size_group: int


INPUTS: Final = ImageArea(
    "inputs",
    IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES,
    IndexGroup.IO_IMAGE_RW_OUTPUT_BITS,
    IndexGroup.IO_IMAGE_OUTPUT_SIZE,
)
OUTPUTS: Final = ImageArea(
    "outputs",
    IndexGroup.IO_IMAGE_RW_INPUT_BYTES,
    IndexGroup.IO_IMAGE_RW_INPUT_BITS,
    IndexGroup.IO_IMAGE_INPUT_SIZE,
)
AREAS: Final = (INPUTS, OUTPUTS)


class ImagePlace:
    """Where a value sits in a process image, and how ADS addresses it: a bit
    field by bit in the bit group, anything else by byte (mixed into classes
    that have `type`, `area` and `bit_address`)."""

    __slots__ = ()
    type: TcType
    area: ImageArea
    bit_address: int

    @property
    def index_group(self) -> int:
        return self.area.bit_group if self.type.is_bit else self.area.byte_group

    @property
    def index_offset(self) -> int:
        return self.bit_address if self.type.is_bit else self.bit_address // 8

    @property
    def size(self) -> int:
        return self.type.symbol_size

    def symbol_entry(self, name: str, comment: str = "") -> AdsSymbolEntry:
        """The 0xF00B / 0xF009 entry of this place under `name`."""
        return AdsSymbolEntry(
            name=name,
            index_group=self.index_group,
            index_offset=self.index_offset,
            size=self.size,
            data_type=self.type.ads_type,
            type_name=self.type.name,
            comment=comment,
            flags=int(SymbolFlag.BIT_VALUE) if self.type.is_bit else 0,
        )


@dataclass(frozen=True, slots=True)
class SymbolDef(ImagePlace):
    """One entry of the device's symbol table."""

    name: str
    type: TcType
    area: ImageArea
    bit_address: int
    slave: int | None = None
    """Position of the slave it belongs to (None: the device itself)."""
    aliases: tuple[str, ...] = ()
    """More names that reach it (`Channel 1.Input` for a one-entry PDO)."""
    runtime: bool = False
    """Computed by the master (WcState, InfoData, Inputs), not by a terminal."""
    comment: str = ""

    def entry(self, name: str | None = None) -> AdsSymbolEntry:
        """The 0xF00B / 0xF009 entry for this symbol."""
        return self.symbol_entry(name or self.name, self.comment)


@dataclass(frozen=True, slots=True)
class SlaveImage:
    """What the master needs to know about one slave's process data."""

    position: int
    datagram: int | None
    """WcState bit of its datagram; None for a slave without process data."""
    has_inputs: bool


@dataclass(frozen=True, slots=True)
class DeviceLayout:
    """The symbol table and image sizes of one device (one master)."""

    symbols: tuple[SymbolDef, ...]
    """Sorted by name, as TwinCAT uploads them."""
    types: tuple[TcType, ...]
    """Named types (0xF00E), in the order first needed."""
    input_size: int
    output_size: int
    inputs_struct: int
    """Byte offset of the master's Inputs in the input image."""
    outputs_struct: int
    slaves: tuple[SlaveImage, ...]
    info_data: dict[int, int] = field(default_factory=dict)
    """Slave position -> byte offset of its InfoData (State, AdsAddr)."""

    def size_of(self, area: ImageArea) -> int:
        return self.input_size if area is INPUTS else self.output_size


@dataclass(slots=True)
class _Placed:
    slave: ResolvedSlave
    symbol: ExpandedSymbol
    type: TcType
    area: ImageArea
    bit_address: int = -1


class _Builder:
    """Lays one master's terminals out into two images and names their types."""

    def __init__(self, master: ResolvedMaster, generation: int) -> None:
        self.master = master
        self.namer = TypeNamer()
        self.shift = GENERATION_SHIFT_BYTES * generation
        self.symbols: list[SymbolDef] = []

    def build(self) -> DeviceLayout:
        placed = [
            self._typed(slave, symbol)
            for slave in self.master.slaves
            for symbol in sorted(slave.active_symbols(), key=_assignment_order)
        ]
        ends = {INPUTS.name: self.shift, OUTPUTS.name: self.shift}
        info_data: dict[int, int] = {}
        info_type = self._info_data_type() if self.master.info_data else None
        for slave in self.master.slaves:
            for item in placed:
                if item.slave is slave and not item.type.is_bit:
                    item.bit_address = 8 * ends[item.area.name]
                    ends[item.area.name] += item.type.byte_size
            if info_type is not None:
                info_data[slave.position] = ends[INPUTS.name]
                self._add_info_data(slave, info_type, ends[INPUTS.name])
                ends[INPUTS.name] += info_type.byte_size
        bit_ends = {name: 8 * end for name, end in ends.items()}
        for item in placed:
            if item.type.is_bit:
                item.bit_address = bit_ends[item.area.name]
                bit_ends[item.area.name] += item.type.bit_size
        inputs_struct = _even((bit_ends[INPUTS.name] + 7) // 8)
        outputs_struct = _even((bit_ends[OUTPUTS.name] + 7) // 8)
        for item in placed:
            self.symbols.append(_symbol_def(item))
        slaves = self._runtime_symbols(placed, inputs_struct, outputs_struct)
        return DeviceLayout(
            symbols=tuple(sorted(self.symbols, key=lambda s: s.name)),
            types=tuple(self.namer.types),
            input_size=inputs_struct + INPUTS_STRUCT_SIZE,
            output_size=outputs_struct + OUTPUTS_STRUCT_SIZE,
            inputs_struct=inputs_struct,
            outputs_struct=outputs_struct,
            slaves=slaves,
            info_data=info_data,
        )

    def _typed(self, slave: ResolvedSlave, symbol: ExpandedSymbol) -> _Placed:
        try:
            return self._type_of(slave, symbol)
        except AdsCodecError as error:
            raise UserError(
                f"{slave.name}: no TwinCAT type for symbol {symbol.name!r}: {error}",
                where=slave.type_name,
            ) from None

    def _type_of(self, slave: ResolvedSlave, symbol: ExpandedSymbol) -> _Placed:
        entries = [
            EntrySpec(m.name, m.type_name, m.bit_offset, m.bit_size)
            for m in symbol.members
        ]
        area = INPUTS if symbol.direction == "input" else OUTPUTS
        family = slave.terminal.symbol_nodes[symbol.node_index].name_template
        if _oversampled(slave, symbol):
            element = pdo_type(
                symbol.name, entries, symbol.sample_bit_size, self.namer, family
            )
            kind = self.namer.register(
                symbol.name,
                array_of(element, symbol.samples),
                suffix="_TYPE_ARR",
                family=family,
            )
        else:
            kind = pdo_type(
                symbol.name, entries, symbol.sample_bit_size, self.namer, family
            )
        return _Placed(slave, symbol, kind, area)

    def _info_data_type(self) -> TcType:
        netid = array_of(scalar_type("USINT", 8), 6)
        address = TcType(
            name="",
            ads_type=AdsDataType.BIGTYPE,
            bit_size=64,
            members=(
                TcMember("netId", netid, 0),
                TcMember("port", scalar_type("UINT", 16), 48),
            ),
        )
        return self.namer.register("AMSADDR", address, suffix="")

    def _add_info_data(
        self, slave: ResolvedSlave, address_type: TcType, offset: int
    ) -> None:
        self.symbols.append(
            SymbolDef(
                f"{slave.name}.InfoData.State",
                scalar_type("UINT", 16),
                INPUTS,
                8 * offset,
                slave=slave.position,
                runtime=True,
            )
        )
        self.symbols.append(
            SymbolDef(
                f"{slave.name}.InfoData.AdsAddr",
                address_type,
                INPUTS,
                8 * (offset + 2),
                slave=slave.position,
                runtime=True,
            )
        )

    def _runtime_symbols(
        self, placed: list[_Placed], inputs_struct: int, outputs_struct: int
    ) -> tuple[SlaveImage, ...]:
        bit = scalar_type("BIT", 1)
        wc_base = 8 * (inputs_struct + FRM0_WCSTATE_OFFSET)
        toggle_base = 8 * (inputs_struct + FRM0_INPUT_TOGGLE_OFFSET)
        images: list[SlaveImage] = []
        for slave in self.master.slaves:
            areas = {item.area.name for item in placed if item.slave is slave}
            has_in, has_out = INPUTS.name in areas, OUTPUTS.name in areas
            datagram = (
                DATAGRAM_IN_OUT
                if has_in and has_out
                else DATAGRAM_OUTPUTS
                if has_out
                else DATAGRAM_INPUTS
                if has_in
                else None
            )
            images.append(SlaveImage(slave.position, datagram, has_in))
            if datagram is None:
                continue
            self.symbols.append(
                SymbolDef(
                    f"{slave.name}.WcState.WcState",
                    bit,
                    INPUTS,
                    wc_base + datagram,
                    slave=slave.position,
                    runtime=True,
                )
            )
            if has_in:
                self.symbols.append(
                    SymbolDef(
                        f"{slave.name}.WcState.InputToggle",
                        bit,
                        INPUTS,
                        toggle_base + datagram,
                        slave=slave.position,
                        runtime=True,
                    )
                )
        inputs = self.namer.register("Inputs", _INPUTS_TYPE)
        outputs = self.namer.register("Outputs", _OUTPUTS_TYPE)
        device = self.master.name
        self.symbols.append(
            SymbolDef(
                f"{device}.Inputs", inputs, INPUTS, 8 * inputs_struct, runtime=True
            )
        )
        self.symbols.append(
            SymbolDef(
                f"{device}.Outputs", outputs, OUTPUTS, 8 * outputs_struct, runtime=True
            )
        )
        self.symbols.append(
            SymbolDef(
                SYNC_UNIT_SYMBOL,
                bit,
                INPUTS,
                8 * (inputs_struct + SYNC_UNIT_OFFSET),
                runtime=True,
            )
        )
        return tuple(images)


def _assignment_order(symbol: ExpandedSymbol) -> int:
    """TwinCAT maps a terminal's PDOs in assignment order (ascending index)."""
    return symbol.pdo_index if symbol.pdo_index is not None else 0x10000


def _oversampled(slave: ResolvedSlave, symbol: ExpandedSymbol) -> bool:
    node = slave.terminal.symbol_nodes[symbol.node_index]
    return node.oversampled


def _symbol_def(item: _Placed) -> SymbolDef:
    symbol = item.symbol
    aliases: tuple[str, ...] = ()
    base = f"{item.slave.name}.{symbol.name}"
    if item.type.scalar is not None and len(symbol.members) == 1:
        aliases = (f"{base}.{symbol.members[0].name}",)
    comment = symbol.members[0].comment if len(symbol.members) == 1 else None
    return SymbolDef(
        base,
        item.type,
        item.area,
        item.bit_address,
        slave=item.slave.position,
        aliases=aliases,
        comment=_windows_text(comment or ""),
    )


def _windows_text(text: str) -> str:
    """TwinCAT writes Windows-1252: characters outside it become '?'."""
    return text.encode(STRING_ENCODING, errors="replace").decode(STRING_ENCODING)


def _even(offset: int) -> int:
    return offset + (offset & 1)


_INPUTS_TYPE: Final = structure(
    "",
    (
        ("Frm0State", "UINT", 0),
        ("Frm0WcState", "UINT", FRM0_WCSTATE_OFFSET),
        ("Frm0InputToggle", "UINT", FRM0_INPUT_TOGGLE_OFFSET),
        ("SlaveCount", "UINT", SLAVE_COUNT_OFFSET),
        ("DevState", "UINT", DEV_STATE_OFFSET),
    ),
    INPUTS_STRUCT_SIZE,
)
_OUTPUTS_TYPE: Final = structure(
    "",
    (("Frm0Ctrl", "UINT", 0), ("Frm0WcCtrl", "UINT", 2), ("DevCtrl", "UINT", 4)),
    OUTPUTS_STRUCT_SIZE,
)


def build_layout(master: ResolvedMaster, generation: int = 0) -> DeviceLayout:
    """The layout of one device; `generation` counts online changes (each
    moves every offset by GENERATION_SHIFT_BYTES)."""
    return _Builder(master, generation).build()


__all__ = [
    "AREAS",
    "INPUTS",
    "OUTPUTS",
    "SYNC_UNIT_SYMBOL",
    "DeviceLayout",
    "ImageArea",
    "SlaveImage",
    "SymbolDef",
    "build_layout",
]
