"""The terminal YAML: one file per terminal type, validated by these models.

A file (`terminals/EL3104.yaml`) holds one mapping whose key is the terminal
type. Everything is generated from the vendor's ESI XML; engineers edit only
the `selected` flags, `selected_pdo_group`, `oversampling.selected_factor`,
`fastcs_name`s and a member's engineering units and alarm severity. Numbers
that engineers know in hex (identity, PDO indices, CoE indices) are written
in hex and load back as ints.

```yaml
# yaml-language-server: $schema=schema.json
EL3104:
  identity:                        # matched against the live terminal
    vendor_id: 0x00000002
    product_code: 0x0c203052
    revision_number: 0x00110000
  description: EL3104 4Ch. Ana. Input +/-10V Diff.
  group_type: AnaIn
  esi_file: Beckhoff EL31xx.xml    # provenance only
  pdo_groups:                      # mutually exclusive PDO assignments
  - name: Standard
    is_default: true
    pdo_indices: [0x1a00, 0x1a02, 0x1a04, 0x1a06]
    symbol_indices: [0]            # positions in symbol_nodes
  - name: Compact
    is_default: false
    pdo_indices: [0x1a01, 0x1a03, 0x1a05, 0x1a07]
    symbol_indices: [1]
  selected_pdo_group: Standard
  symbol_nodes:                    # one node per PDO (or per PDO x channels)
  - name_template: AI Standard Channel {channel}
    fastcs_name: ai_standard_channel_{channel}
    selected: true
    channels: [1, 2, 3, 4]
    pdo_indices: [0x1a00, 0x1a02, 0x1a04, 0x1a06]   # one per channel
    direction: input               # TxPDO; an RxPDO is `output`
    access: ro                     # `rw` for outputs
    type_name: AI Standard Channel {channel}_TYPE
    bit_size: 32
    members:                       # every PDO entry except gaps
    - name: Status__Underrange
      fastcs_name: status_underrange
      type_name: BIT
      bit_offset: 0                # within the symbol
      bit_size: 1
      coe: ['0x6000:01', '0x6010:01', '0x6020:01', '0x6030:01']  # per channel
      comment: Bit set when upper value limit exceeded
    - name: Value
      fastcs_name: value
      type_name: INT
      bit_offset: 16
      bit_size: 16
      coe: ['0x6000:11', '0x6010:11', '0x6020:11', '0x6030:11']
      dscale: +/-10                # served in volts: 10 V / 32767 per count
      # unit: mV                   # overrides (terminals units): scale,
      # scale: 0.30518             #   offset, unit, precision
  - name_template: AI Compact Channel {channel}
    ...
  coe_objects:
  - index: 0x8000
    name: AI Settings
    fastcs_name: ai_settings_8000
    selected: false                # CoE objects start unselected
    type_name: DT8000
    bit_size: 160
    access: rw
    sub_items:
    - subindex: 0x02
      name: Presentation
      fastcs_name: presentation
      type_name: DT0800EN03
      bit_size: 3
      bit_offset: 17
      access: rw
      default_data: '00'           # ESI DefaultData: little-endian hex bytes
      enum:
      - {value: 0, text: Signed}
```

Oversampling terminals add (EL3702; ELM37xx has `by_group: true` and an
`oversampling_factor` on each PDO group instead of `oversampled` symbols):

```yaml
  oversampling:
    factors: [1, 2, 3, 4, 5, 8, 10, 16, 20, 25, 32, 40, 50, 100]
    default_factor: 10
    selected_factor: 10
    pdo_indices: [0x1a00, 0x1a80]
  symbol_nodes:
  - name_template: Ch{channel} Sample 0
    type_name: Ch{channel} Sample 0_TYPE_ARR
    bit_size: 16                   # one sample
    oversampled: true
    ...
```

Meaning, for the simulator and the IOC:

- A symbol node stands for one TwinCAT I/O symbol per channel, named
  `<terminal name>.<name_template with {channel}>` (`Term 5 (EL3104).AI
  Standard Channel 1`). `channels` is empty for a PDO without a channel; then
  `name_template` has no `{channel}` and `pdo_indices` has one entry.
  Position k of `channels`, `pdo_indices` and every member's `coe` belong
  together. Empty `pdo_indices` / `coe` mean "not known" (a hand-written
  description); generated and imported files always have them.
- `type_name` is the symbol's TwinCAT type: `<PDO name>_TYPE` (a BIGTYPE
  structure) for a PDO with several entries or a nested entry name; the
  entry's own scalar type (`BIT`, `INT`, `UDINT`, ...) for a single-entry PDO.
  A 1-bit `BOOL` entry is a `BIT`, as in the TwinCAT I/O tree.
- `bit_size` is the PDO's size including gaps; members carry their bit offset
  in the symbol. Entry names keep the ESI spelling: `Status__Underrange` is
  the bit `Underrange` of the status word (TwinCAT shows it as
  `Status.Underrange`); `members` lists each such bit on its own.
- `oversampled: true` marks a PDO whose entries repeat once per sample: the
  symbol holds `oversampling.selected_factor` copies of the members, so its
  real size is `bit_size * selected_factor` (see `expanded_symbols`). Its
  name and type (`Ch1 Sample 0`, `Ch1 Sample 0_TYPE_ARR`, an array of
  samples) follow catio's table of real TwinCAT symbols.
- `selected` says whether the IOC makes PVs for a symbol or CoE object (a
  CoE sub-item may say `selected: false` to leave out one sub-index). A
  symbol that belongs to PDO groups is selectable only in the selected group;
  symbols of the other groups are saved with `selected: false`. Symbols in
  no group are optional PDOs (ELM37xx control PDOs, EL3356 timestamp...):
  they start unselected on a terminal with groups, all symbols start
  selected on one without, and their flag is the engineer's to set.
- `pdo_groups` come from the ESI (`AlternativeSmMapping`, or `Exclude`
  chains); the `is_default` group is what TwinCAT assigns to a new terminal.
  Which PDOs are really active is decided by the live symbol table.
- A member's value is served in engineering units where its `dscale`
  says what a count means (`terminals.meaning`), or where the engineer set
  `scale`, `offset`, `unit` or `precision` (on top of what `dscale` gives);
  the raw count keeps a PV of its own. A status bit or field carries the
  alarm severity its name implies while set (`Error` MAJOR, `Underrange`
  MINOR, ...) unless `severity` (none, minor, major) says otherwise. These
  five keys are the engineer's: regenerate keeps them.
- `fastcs_name`s are unique in a terminal (symbols with `{channel}` once
  expanded, CoE objects), members and sub-items unique in their parent.
  Symbol names need not be: some ESI files name several PDOs alike (EL1262,
  EL3773); `pdo_indices` tell such symbols apart.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StringConstraints,
    field_validator,
)

from fastcs_ethercat.bounded import no_bool_for_number
from fastcs_ethercat.esi.model import (
    MAX_ESI_BITS,
    MAX_PDO_BITS,
    MAX_PDO_ENTRY_BITS,
    MAX_SM_PDOS,
)
from fastcs_ethercat.terminals.names import CHANNEL, expand
from fastcs_ethercat.terminals.yaml_style import (
    FLOW_DICT,
    FLOW_LIST,
    Hex8,
    Hex16,
    Hex32,
)

Direction = Literal["input", "output"]
SeverityName = Literal["none", "minor", "major"]
"""Alarm severity of a status bit or field while it is set."""
MAX_UNIT_LENGTH = 15
"""A record's EGU holds 16 bytes with its NUL."""
UNIT_CHOICES = ("scale", "offset", "unit", "precision")
"""A member's engineering-unit overrides (`terminals units`)."""
MEMBER_CHOICES = (*UNIT_CHOICES, "severity")
"""A member's keys that are the engineer's (regenerate keeps them)."""
SymbolAccess = Literal["ro", "rw"]
CoeAccess = Literal["ro", "rw", "wo"]

CoeAddress = Annotated[str, StringConstraints(pattern=r"^0x[0-9a-f]{4}:[0-9a-f]{2}$")]
"""A CoE object address `0x6000:11` (index:subindex, hex)."""

FastcsName = Annotated[
    str,
    StringConstraints(pattern=r"^[a-z][a-z0-9_]*(\{channel\}[a-z0-9_]*)*$"),
]
"""snake_case attribute name; may hold `{channel}`."""

# Every number has the range EtherCAT allows it, which real files keep well
# inside (`esi.model` says why each bound is what it is): a terminal file is
# edited by hand, and a huge number must be one line naming it, not a
# process image of gigabytes in the simulator or a PV nobody can serve.
PdoBits = Annotated[int, Field(ge=1, le=MAX_PDO_BITS)]
"""A PDO's size in bits."""
EntryBits = Annotated[int, Field(ge=1, le=MAX_PDO_ENTRY_BITS)]
"""One PDO entry's size."""
CoeBits = Annotated[int, Field(ge=0, le=MAX_ESI_BITS)]
"""A CoE object's (or sub-index's) size or offset: as far as the ESI reader
goes (Beckhoff's dictionaries: at most 11 264 bits)."""
Samples = Annotated[int, Field(ge=1, le=MAX_SM_PDOS)]
"""An oversampling factor."""
EnumValue = Annotated[int, Field(ge=-(1 << 63), le=(1 << 64) - 1)]
"""A CoE enum value: 64 bits at most, signed or not."""

HexList = Annotated[list[Hex16], FLOW_LIST]
IntList = Annotated[list[Annotated[int, Field(ge=0)]], FLOW_LIST]
ChannelList = Annotated[list[Annotated[int, Field(ge=0, le=MAX_SM_PDOS)]], FLOW_LIST]
FactorList = Annotated[list[Samples], FLOW_LIST]
CoeList = Annotated[list[CoeAddress], FLOW_LIST]


def coe_address(index: int, subindex: int) -> str:
    """The YAML spelling of a CoE address: `0x6000:11`."""
    return f"0x{index:04x}:{subindex:02x}"


def parse_coe_address(text: str) -> tuple[int, int]:
    """`0x6000:11` -> (0x6000, 0x11)."""
    index, subindex = text.split(":")
    return int(index, 16), int(subindex, 16)


class _Model(BaseModel):
    """Unknown keys are errors: a typo must not silently become a default.

    Validators are built at the first validation, not at import: an IOC or
    simulator start takes its terminal types from the cache (`load_cache`)
    and validates none (building them was 10 ms of every start)."""

    model_config = ConfigDict(extra="forbid", defer_build=True)
    _no_bool_for_number = field_validator("*", mode="before")(no_bool_for_number)


class Identity(_Model):
    """What the terminal reports over EtherCAT (CoE 0x1018)."""

    vendor_id: Hex32 = Field(description="EtherCAT vendor id (Beckhoff: 0x2).")
    product_code: Hex32 = Field(description="Product code from the ESI `Type`.")
    revision_number: Hex32 = Field(description="Revision from the ESI `Type`.")


class PdoGroup(_Model):
    """One mutually exclusive PDO assignment TwinCAT can be configured with."""

    name: str = Field(description="Group name from the ESI (e.g. Standard).")
    is_default: bool = Field(description="The assignment of a new terminal.")
    pdo_indices: HexList = Field(description="PDOs assigned in this group.")
    symbol_indices: IntList = Field(
        description="Positions in symbol_nodes of the symbols of this group."
    )
    oversampling_factor: Samples | None = Field(
        default=None,
        description="Samples per cycle this group implies (ELM37xx), if any.",
    )


MEMBER_GROUP_JOIN = "__"
"""Joins an entry's group and name in a member's `name` (`Status__Error`)."""


class SymbolMember(_Model):
    """One PDO entry inside a symbol (gaps are left out)."""

    name: str = Field(description="Entry name as in the ESI; may hold {channel}.")
    fastcs_name: FastcsName = Field(description="Attribute name within the symbol.")
    type_name: str = Field(description="TwinCAT type: BIT, BIT2, INT, UDINT...")
    bit_offset: int = Field(
        ge=0, le=MAX_PDO_BITS, description="Bit offset within the symbol."
    )
    bit_size: EntryBits = Field(description="Size in bits.")
    coe: CoeList = Field(description="CoE index:subindex mapped, per channel.")
    comment: str | None = Field(default=None, description="ESI entry comment.")
    dscale: str | None = Field(
        default=None, description="ESI `DScale` of the value (e.g. +/-10)."
    )
    scale: float | None = Field(
        default=None,
        allow_inf_nan=False,
        description="Override: engineering value per count (raw * scale + offset).",
    )
    offset: float | None = Field(
        default=None,
        allow_inf_nan=False,
        description="Override: engineering value at count 0.",
    )
    unit: str | None = Field(
        default=None,
        description="Override: engineering unit (EGU, e.g. V, mA, degC).",
    )
    precision: int | None = Field(
        default=None, ge=0, le=15, description="Override: decimals shown (PREC)."
    )
    severity: SeverityName | None = Field(
        default=None,
        description="Override: alarm severity while the bit or field is set "
        "(none, minor, major).",
    )

    @field_validator("scale")
    @classmethod
    def _scale_is_not_zero(cls, scale: float | None) -> float | None:
        if scale == 0:
            raise ValueError("a scale of 0 maps every count to one value")
        return scale

    @field_validator("unit")
    @classmethod
    def _unit_fits_egu(cls, unit: str | None) -> str | None:
        if unit is not None and len(unit.encode("utf-8")) > MAX_UNIT_LENGTH:
            raise ValueError(
                f"{unit!r} is longer than a record's EGU "
                f"({MAX_UNIT_LENGTH} bytes in UTF-8)"
            )
        return unit

    def address(self, position: int) -> tuple[int, int]:
        """(index, subindex) of this entry for the channel at `position`."""
        return parse_coe_address(self.coe[position])

    @property
    def shown_name(self) -> str:
        """The name as people read and type it: `Status.Underrange` (the file
        keeps the generator's `Status__Underrange`)."""
        return self.name.replace(MEMBER_GROUP_JOIN, ".")


class SymbolNode(_Model):
    """A PDO as a TwinCAT I/O symbol, once per channel."""

    name_template: str = Field(
        description="Symbol name after the terminal name; {channel} per channel."
    )
    fastcs_name: FastcsName = Field(description="Attribute/PV base name.")
    selected: bool = Field(description="Whether the IOC makes PVs for it.")
    channels: ChannelList = Field(
        default_factory=list, description="Channel numbers; empty: no channel."
    )
    pdo_indices: HexList = Field(description="The PDO index per channel.")
    direction: Direction = Field(description="input (TxPDO) or output (RxPDO).")
    access: SymbolAccess = Field(description="ro for inputs, rw for outputs.")
    type_name: str = Field(description="TwinCAT type name of the symbol.")
    bit_size: PdoBits = Field(description="PDO size in bits (one sample).")
    oversampled: bool = Field(
        default=False,
        description="Entries repeat once per sample (oversampling factor).",
    )
    members: list[SymbolMember] = Field(description="The PDO's entries.")

    def channel_positions(self) -> Iterator[tuple[int, int | None]]:
        """(position, channel) pairs; one (0, None) for a channel-less PDO."""
        if not self.channels:
            yield 0, None
            return
        yield from enumerate(self.channels)

    def names(self) -> list[str]:
        """The concrete symbol names, one per channel."""
        return [expand(self.name_template, ch) for _, ch in self.channel_positions()]


class CoeEnumItem(_Model):
    """One value/text pair of an enumerated CoE type."""

    value: EnumValue
    text: str


EnumList = list[Annotated[CoeEnumItem, FLOW_DICT]]


class CoeSubItem(_Model):
    """One sub-index of a CoE record or array."""

    subindex: Hex8 = Field(description="Sub-index.")
    name: str
    fastcs_name: FastcsName = Field(description="Attribute name within the object.")
    selected: bool = Field(
        default=True,
        description="Off: no PV for this sub-index even when its object is "
        "selected (written only when off).",
    )
    type_name: str
    bit_size: CoeBits
    bit_offset: CoeBits = 0
    access: CoeAccess | None = None
    default_data: str | None = Field(
        default=None, description="ESI DefaultData: little-endian hex bytes."
    )
    default_value: str | None = Field(default=None, description="ESI DefaultValue.")
    min_value: str | None = None
    max_value: str | None = None
    unit: str | None = None
    enum: EnumList = Field(default_factory=list, description="Enum value texts.")


class CoeObject(_Model):
    """A CoE dictionary object the IOC may expose (when selected)."""

    index: Hex16 = Field(description="Object index.")
    name: str
    fastcs_name: FastcsName = Field(description="Attribute/PV base name.")
    selected: bool = Field(description="Whether the IOC exposes this object.")
    type_name: str
    bit_size: CoeBits
    access: CoeAccess | None = None
    default_data: str | None = Field(
        default=None, description="ESI DefaultData: little-endian hex bytes."
    )
    default_value: str | None = None
    min_value: str | None = None
    max_value: str | None = None
    unit: str | None = None
    enum: EnumList = Field(default_factory=list, description="Enum value texts.")
    sub_items: list[CoeSubItem] = Field(
        default_factory=list, description="Sub-indices of a record or array."
    )

    def access_of(self, item: CoeObject | CoeSubItem) -> CoeAccess | None:
        """A sub-item without an access of its own has its object's (the IOC
        and the simulator both judge writes by this)."""
        return item.access or self.access


class Oversampling(_Model):
    """Samples per cycle of an oversampling terminal (EL37xx, EL47xx, ELM37xx)."""

    factors: FactorList = Field(description="Factors the ESI offers, ascending.")
    default_factor: Samples = Field(description="Factor of a new terminal.")
    selected_factor: Samples = Field(description="Factor configured in TwinCAT.")
    pdo_indices: HexList = Field(description="PDOs holding the samples.")
    by_group: bool = Field(
        default=False,
        description="The factor follows the selected PDO group (ELM37xx).",
    )


class TerminalType(_Model):
    """Everything the IOC and the simulator need about one terminal type."""

    identity: Identity
    description: str
    group_type: str | None = Field(default=None, description="ESI GroupType.")
    esi_file: str | None = Field(
        default=None, description="ESI file it was generated from (name only)."
    )
    pdo_groups: list[PdoGroup] = Field(
        default_factory=list, description="Exclusive PDO groups; empty: static."
    )
    selected_pdo_group: str | None = Field(
        default=None, description="The PDO group configured in TwinCAT."
    )
    oversampling: Oversampling | None = None
    symbol_nodes: list[SymbolNode] = Field(description="Every PDO as a symbol.")
    coe_objects: list[CoeObject] = Field(description="The CoE dictionary.")

    @property
    def has_pdo_groups(self) -> bool:
        return bool(self.pdo_groups)

    def group(self, name: str) -> PdoGroup:
        """The PDO group called `name`; KeyError if there is none."""
        for group in self.pdo_groups:
            if group.name == name:
                return group
        raise KeyError(name)

    @property
    def default_group(self) -> PdoGroup | None:
        return next((g for g in self.pdo_groups if g.is_default), None)

    @property
    def active_group(self) -> PdoGroup | None:
        """The selected group, else the default one; None without groups."""
        if self.selected_pdo_group is not None:
            for group in self.pdo_groups:
                if group.name == self.selected_pdo_group:
                    return group
        return self.default_group

    def groups_of(self, symbol_index: int) -> list[str]:
        """Names of the PDO groups a symbol node belongs to."""
        return [g.name for g in self.pdo_groups if symbol_index in g.symbol_indices]

    def selectable(self, symbol_index: int) -> bool:
        """Whether a symbol may be selected under the current group choice."""
        groups = self.groups_of(symbol_index)
        return not groups or self.selected_pdo_group in groups

    def served_nodes(self, running_group: str | None) -> list[int]:
        """Indices of the symbol nodes served while the PLC runs
        `running_group`: the selected groupless ones, then the selected ones
        of that group. When the YAML selects another group and selects none
        of the running one, every node of the running group is served."""
        grouped = {i for g in self.pdo_groups for i in g.symbol_indices}
        free = [i for i in range(len(self.symbol_nodes)) if i not in grouped]
        running = (
            sorted(self.group(running_group).symbol_indices) if running_group else []
        )
        chosen = self.active_group
        picked = [i for i in running if self.symbol_nodes[i].selected]
        if chosen is not None and chosen.name != running_group and not picked:
            picked = running
        return [i for i in free if self.symbol_nodes[i].selected] + picked

    def served_coe_objects(self) -> list[CoeObject]:
        """The CoE objects served (read at start, written as SDOs)."""
        return [obj for obj in self.coe_objects if obj.selected]

    def sample_count(self, node: SymbolNode) -> int:
        """How many copies of the members an instance of `node` holds."""
        if node.oversampled and self.oversampling is not None:
            return self.oversampling.selected_factor
        return 1


__all__ = [
    "CHANNEL",
    "MEMBER_CHOICES",
    "UNIT_CHOICES",
    "CoeEnumItem",
    "CoeObject",
    "CoeSubItem",
    "Identity",
    "Oversampling",
    "PdoGroup",
    "SeverityName",
    "SymbolMember",
    "SymbolNode",
    "TerminalType",
    "coe_address",
    "parse_coe_address",
]
