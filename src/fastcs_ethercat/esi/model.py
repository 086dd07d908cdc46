"""Typed, immutable description of what an ESI file says about one device.

These classes are the contract between the ESI parser and everything that
consumes it (the terminal-YAML generator first of all). Public names are kept
stable; new fields are only ever added with defaults.

All are immutable. The records a full parse builds by the ten thousand (PDO
entries, data types, CoE objects and their sub-items: ~100 000 for the 506
devices of the shared files) are `NamedTuple`s: built several times faster
than frozen dataclasses (which set each field through `object.__setattr__`),
and the build was a fifth of a full parse. Use them by field name; being
tuples is not part of the contract (their `index` field hides the tuple
method of that name, hence the pyright ignores). The few records that hold a mapping
(`EsiPdoGroup`, `EsiOversampling`, `EsiDevice`) stay frozen dataclasses.

Numbers are plain ints (indices, product codes, revisions); the ESI spelling
(`#x1a00`, `#X1A00`, decimal) is normalised by `parse_esi_int`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

PdoDirection = Literal["tx", "rx"]
"""`tx`: TxPdo, inputs to the controller; `rx`: RxPdo, outputs from it."""

Access = Literal["ro", "rw", "wo"]
GroupOrigin = Literal["alternative_sm_mapping", "exclude"]


ESI_INT_CHARS = 20
"""The longest spelling of an ESI number: 2**64 - 1 has 20 decimal digits."""
MAX_ESI_BITS = 1 << 20
"""The most bits an ESI BitLen or BitSize may give (real files: under 12 000)."""
MAX_PDO_ENTRY_BITS = 255
"""The most bits one PDO entry can have: an entry of a PDO mapping object
(0x1600.., 0x1A00..) is 32 bits of index (16), sub-index (8) and bit length
(8). Beckhoff's ESI files: at most 64."""
MAX_PDO_ENTRIES = 255
"""The most entries one PDO can map: its mapping object's sub-index 0, the
count, is one byte. Beckhoff's ESI files: 100 (ELM3704's samples)."""
MAX_PDO_BITS = MAX_PDO_ENTRIES * MAX_PDO_ENTRY_BITS
"""The most bits one PDO can hold (65 025). Beckhoff's ESI files: 3 200."""
MAX_SM_PDOS = 255
"""The most PDOs a sync manager can be assigned (0x1C12/0x1C13: the count
in sub-index 0 is one byte), so the most channels a terminal's PDOs name
and samples per cycle it can take. Beckhoff's ESI files: channels up to
16, oversampling factors up to 128."""


def parse_esi_int(text: str) -> int:
    """Parse an ESI number: `#x1a00`, `#X1A00`, `0x1a00`, `4096`, `-5`.

    Raises ValueError for anything else, and for a magnitude of 2**64 or
    more (no ESI field holds one), so the caller can name the place.
    """
    value = text.strip()
    sign = 1
    if value.startswith("-"):
        sign, value = -1, value[1:]
    if len(value) > ESI_INT_CHARS:  # before int(): 5 000 digits cost a lot
        raise ValueError(f"{len(value)} characters is too long for a number")
    if value[:2] in ("#x", "#X", "0x", "0X"):
        number = int(value[2:], 16)
    else:
        number = int(value, 10)
    if number >= 1 << 64:
        raise ValueError("out of range (2**64 or more)")
    return sign * number


new_record = tuple.__new__
"""`new_record(EsiEntry, (...))`: a record from a tuple of all its fields in
order, for the hot loops (NamedTuple's own `__new__` is a Python function,
several times slower)."""


class EsiEntry(NamedTuple):
    """One PDO entry: a mapped object (or a gap, when `index` is 0)."""

    index: int  # pyright: ignore[reportIncompatibleMethodOverride]
    subindex: int
    bit_len: int
    name: str
    data_type: str | None
    comment: str | None = None
    dscale: str | None = None
    """The `DScale` attribute of `DataType` (e.g. "+/-10", "0-10"), if any."""

    @property
    def is_padding(self) -> bool:
        """Gap entries (index #x0) only reserve bits; TwinCAT makes no symbol."""
        return self.index == 0


class EsiPdo(NamedTuple):
    """A TxPdo (inputs) or RxPdo (outputs) with its entries."""

    index: int  # pyright: ignore[reportIncompatibleMethodOverride]
    name: str
    direction: PdoDirection
    sm: int | None
    """Sync manager the PDO is assigned to by default; None: not by default."""
    fixed: bool
    mandatory: bool
    excludes: tuple[int, ...]
    entries: tuple[EsiEntry, ...]
    channel: int | None = None
    """Channel number found in the name ("AI Standard Channel 2" -> 2)."""
    channel_template: str | None = None
    """Name with the channel as `{channel}` ("AI Standard Channel {channel}")."""
    virtual: bool = False
    su: int | None = None
    os_factor: int | None = None
    """`OSFac`: default oversampling factor of an oversampling PDO."""
    os_min: int | None = None
    os_max: int | None = None
    os_index_inc: int | None = None
    """`OSIndexInc`: entry-index step between successive samples."""

    @property
    def is_oversampling(self) -> bool:
        """True when the entries are a template repeated once per sample."""
        return self.os_factor is not None


@dataclass(frozen=True, slots=True)
class EsiPdoGroup:
    """One mutually exclusive PDO configuration TwinCAT can select."""

    name: str
    is_default: bool
    pdo_indices: tuple[int, ...]
    """Every PDO of the group, all sync managers together, in file order."""
    sm_pdos: Mapping[int, tuple[int, ...]]
    """Sync manager number -> PDO indices assigned to it in this group."""
    origin: GroupOrigin = "alternative_sm_mapping"
    pdo_channels: Mapping[int, int] = field(default_factory=dict)
    """PDO index -> `ChannelNo` where the file gives one (ELM37xx)."""
    operation_modes: tuple[str, ...] = ()
    """Names of the `OperationMode`s of this mapping (ELM37xx), if any."""
    unknown_pdo_indices: tuple[int, ...] = ()
    """PDOs the mapping names but the device does not define (EL2014)."""


class EsiEnumItem(NamedTuple):
    """One value/text pair of an enumerated data type."""

    value: int
    text: str


class EsiDataTypeSubItem(NamedTuple):
    """A member of a structured data type (record/array element)."""

    subindex: int | None
    name: str
    type_name: str
    bit_size: int
    bit_offset: int
    access: Access | None = None
    pdo_mapping: str | None = None
    """`Flags/PdoMapping` ("T", "R", "TR"), if the item may be mapped."""


class EsiDataType(NamedTuple):
    """A `DataTypes/DataType` of the device's CoE dictionary."""

    name: str
    bit_size: int
    base_type: str | None = None
    enum_items: tuple[EsiEnumItem, ...] = ()
    sub_items: tuple[EsiDataTypeSubItem, ...] = ()
    array_lbound: int | None = None
    array_elements: int | None = None


class EsiCoeSubItem(NamedTuple):
    """One sub-index of a CoE object, with type facts and defaults merged."""

    index: int  # pyright: ignore[reportIncompatibleMethodOverride]
    subindex: int
    name: str
    type_name: str
    bit_size: int
    bit_offset: int = 0
    access: Access | None = None
    pdo_mapping: str | None = None
    default_data: str | None = None
    """`DefaultData`: little-endian hex bytes as written in the file."""
    default_value: str | None = None
    min_value: str | None = None
    max_value: str | None = None
    unit: str | None = None
    enum_items: tuple[EsiEnumItem, ...] = ()
    """Enum texts of the sub-item's data type, if it is an enum."""


class EsiCoeObject(NamedTuple):
    """A CoE dictionary object (`Objects/Object`)."""

    index: int  # pyright: ignore[reportIncompatibleMethodOverride]
    name: str
    type_name: str
    bit_size: int
    access: Access | None = None
    pdo_mapping: str | None = None
    category: str | None = None
    default_data: str | None = None
    sub_items: tuple[EsiCoeSubItem, ...] = ()
    """Sub-indices of a record/array object; empty for a simple object."""
    enum_items: tuple[EsiEnumItem, ...] = ()


class EsiSyncManager(NamedTuple):
    """A `<Sm>` element: its position in the device's list is its number."""

    number: int
    kind: str
    """Element text: "MBoxOut", "MBoxIn", "Outputs", "Inputs"."""
    start_address: int | None = None
    default_size: int | None = None


class EsiDcOpModePdo(NamedTuple):
    """A PDO assignment inside a DC `OpMode`, with its oversampling factor."""

    sm: int
    pdo_index: int
    os_factor: int | None


class EsiDcOpMode(NamedTuple):
    """A distributed-clock operating mode (`Dc/OpMode`)."""

    name: str
    description: str
    assign_activate: int | None
    pdos: tuple[EsiDcOpModePdo, ...] = ()
    default_os_factor: int | None = None
    """`VendorSpecific/TwinCAT/Oversampling@DefaultFactor`, if given."""


@dataclass(frozen=True, slots=True)
class EsiOversampling:
    """How the device repeats sample entries (EL37xx, EL47xx, ELM37xx)."""

    factors: tuple[int, ...]
    """Factors the file offers, ascending."""
    default_factor: int | None
    pdo_indices: tuple[int, ...]
    """PDOs whose entries are the sample arrays."""
    min_factor: int | None = None
    max_factor: int | None = None
    index_increment: int | None = None
    """Step of the entry index per sample (`OSIndexInc`), if given."""
    origin: Literal["pdo_attributes", "pdo_groups"] = "pdo_attributes"
    """`pdo_attributes`: OSFac/OSMin/OSMax on PDOs plus DC op modes (EL37xx,
    EL47xx); `pdo_groups`: one PDO group per factor (ELM37xx)."""
    group_factors: Mapping[str, int] = field(default_factory=dict)
    """For `pdo_groups`: group name -> oversampling factor."""


class EsiHideType(NamedTuple):
    """A `HideType`: an older identity TwinCAT should hide behind this one."""

    product_code: int | None
    revision: int | None
    name: str


@dataclass(frozen=True, slots=True)
class EsiDevice:
    """Everything the parser knows about one `<Device>` (one revision)."""

    type_name: str
    vendor_id: int
    product_code: int
    revision: int
    description: str
    """English name (LcId 1033), else the first name in the file."""
    group_type: str
    tx_pdos: tuple[EsiPdo, ...]
    rx_pdos: tuple[EsiPdo, ...]
    pdo_groups: tuple[EsiPdoGroup, ...]
    """Alternative PDO configurations (see `groups` for the rules); empty
    for a terminal with a static PDO configuration."""
    default_group: str | None
    """Name of the group TwinCAT assigns by default, if any."""
    data_types: Mapping[str, EsiDataType]
    """The CoE dictionary's `DataTypes` by name (empty without dictionary)."""
    coe_objects: Mapping[int, EsiCoeObject]
    """The CoE dictionary's objects by index, in file order."""
    oversampling: EsiOversampling | None
    source: str
    """Document it came from: a path, or `<zip>!<member>` inside a zip."""
    source_line: int
    """Line of the `<Device>` start tag in that document."""
    names: Mapping[int, str] = field(default_factory=dict)
    """All names by LcId (1033 English, 1031 German, ...)."""
    hide_types: tuple[EsiHideType, ...] = ()
    sync_managers: tuple[EsiSyncManager, ...] = ()
    dc_op_modes: tuple[EsiDcOpMode, ...] = ()
    has_mailbox: bool = False
    has_coe: bool = False

    @property
    def pdos(self) -> tuple[EsiPdo, ...]:
        """Inputs first, then outputs, each in file order."""
        return self.tx_pdos + self.rx_pdos

    @property
    def has_pdo_groups(self) -> bool:
        return bool(self.pdo_groups)

    def pdo(self, index: int) -> EsiPdo:
        """The PDO with this index; KeyError if the device has none."""
        for pdo in self.pdos:
            if pdo.index == index:
                return pdo
        raise KeyError(f"{self.type_name} has no PDO {index:#06x}")

    def group(self, name: str) -> EsiPdoGroup:
        """The PDO group with this name; KeyError if the device has none."""
        for group in self.pdo_groups:
            if group.name == name:
                return group
        raise KeyError(f"{self.type_name} has no PDO group {name!r}")


@dataclass(frozen=True, slots=True)
class CatalogEntry:
    """One device (type + revision) in a catalog: cheap to build and cache."""

    type_name: str
    revision: int
    product_code: int
    vendor_id: int
    group_type: str
    has_pdo_groups: bool
    description: str
    source: str
    """File path (inside a zip: `<zip>!<member>`)."""
    line: int
    """Line of the `<Device>` start tag in the source file."""
    device_position: int = 0
    """0-based position of the device among the file's `<Device>`s."""
    problem: str | None = None
    """Why the device does not parse (one line), None when it does."""
    hides: tuple[int, ...] = ()
    """Revisions of its own product this device hides (`HideType`): older
    ones, and catalogue placeholders like #x270b0000 ("-9995")."""

    @property
    def parses(self) -> bool:
        return self.problem is None
