"""What discovery found and what the IOC will serve: the contract between the
data plane (discovery, symbol resolution, polling) and the FastCS side
(controllers, attributes, PV names).

Discovery fills these from the live system (the I/O server, each EtherCAT
master, the live symbol and data-type tables) and the terminal YAML; the
controllers turn each `Point` into one FastCS attribute and the poller reads
every `Point` of a master in sum reads. Plain frozen dataclasses so that both
sides can be built and tested apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from fastcs_ethercat.ads.ethercat import SlaveIdentity
from fastcs_ethercat.terminals.meaning import Scaling


class PointKind(Enum):
    """How a point's value sits in the bytes of its symbol."""

    SCALAR = "scalar"  # a whole number/float/bool/string of `type_name`
    BIT = "bit"  # one bit: `bit_offset` within the read bytes
    BITS = "bits"  # an unsigned field of `bit_size` bits at `bit_offset`
    ARRAY = "array"  # `length` elements of `type_name` (oversampling samples)


@dataclass(frozen=True, slots=True)
class Source:
    """The live symbol whose value holds a point's bytes, as the live table
    described it at discovery: a handle per source is read each cycle, and
    not used when its symbol now has another type or size (it would misread
    the bytes)."""

    name: str
    offset: int = 0  # byte of the point's bytes within the source's value
    type_name: str = ""  # "" / 0: the point's own type and size
    size: int = 0


@dataclass(frozen=True, slots=True)
class Point:
    """One value the IOC serves: a TwinCAT symbol or one member of it.

    The IOC reads and writes by symbol handle, never by address: an online
    change then makes a request fail (0x711) instead of touching other
    bytes. `source` is where a read finds the point's bytes; `symbol` itself
    is what a write's handle names (a member reaches its own bytes, a bit
    member its own bit). A bit symbol of the bit-addressed image
    reads by handle as one byte, its value in bit 0.

    `index_group`/`index_offset` are where the live table put the point at
    discovery (the symbol's address moved to the member's byte): a record of
    that moment, never used to read or write.
    """

    key: str  # stable id, unique within the IOC: "<master>/<slave>/<symbol>"
    symbol: str  # full TwinCAT name, e.g. "Term 5 (EL3104).AI Standard Channel 1.Value"
    attribute: str  # FastCS attribute name within the terminal, snake_case
    type_name: str  # TwinCAT type of the value, e.g. "INT", "BIT", "REAL", "UDINT"
    kind: PointKind
    index_group: int
    index_offset: int
    byte_size: int
    bit_offset: int = 0
    bit_size: int = 0
    length: int = 1  # elements, for ARRAY
    writable: bool = False  # an RxPDO output
    description: str = ""  # DESC: from the ESI's names, within 40 characters
    enum_texts: tuple[tuple[int, str], ...] = ()
    scaling: Scaling | None = None  # engineering units (terminals.meaning)
    severity: int = 0  # EPICS alarm severity while a status bit/field is set
    channel: int | None = None
    """The terminal channel it belongs to (its PV sits under `CH<n>`)."""
    entry_name: str = ""
    """The ESI entry it reads within its symbol (`Status.Underrange`, `Value`):
    its PV name; "" names it by its symbol."""
    source: Source | None = None  # None: `symbol` itself, from its first byte

    @property
    def source_name(self) -> str:
        """The symbol a read handle is taken for."""
        return self.symbol if self.source is None else self.source.name

    @property
    def source_offset(self) -> int:
        """Byte of the point's bytes within its source's value."""
        return 0 if self.source is None else self.source.offset

    @property
    def source_shape(self) -> tuple[str, int]:
        """(type, size) the source had at discovery."""
        source = self.source
        if source is None:
            return (self.type_name, self.byte_size)
        return (source.type_name or self.type_name, source.size or self.byte_size)

    def __repr__(self) -> str:
        """Short: FastCS logs a failed put with its attribute, whose reference
        holds the point (every field would be a line of 1 000 characters)."""
        return f"Point({self.symbol!r})"


@dataclass(frozen=True, slots=True)
class CoePoint:
    """One CoE object sub-item the terminal's YAML selects (read via SDO)."""

    attribute: str
    index: int
    subindex: int
    type_name: str
    bit_size: int
    writable: bool
    description: str = ""
    default: str = ""
    enum_texts: tuple[tuple[int, str], ...] = ()
    units: str = ""  # EGU, from the ESI's unit code
    name: str = ""
    """The sub-item's ESI name (the object's when it has none): its PV name."""
    object_name: str = ""
    """The object's ESI name (`AI Settings`): its screen group."""

    def __repr__(self) -> str:
        """Short, as `Point`'s: a failed CoE put is logged with its attribute,
        whose reference holds this (its description and enum texts would
        make a line of hundreds of characters)."""
        return f"CoePoint(0x{self.index:04x}:{self.subindex:02x} {self.name!r})"


@dataclass(frozen=True, slots=True)
class SlaveInfo:
    """One EtherCAT slave as the master reports it."""

    address: int  # EtherCAT address, 1001, 1002, ...
    name: str  # TwinCAT name, "Term 5 (EL3104)"
    identity: SlaveIdentity  # vendor, product code, revision, serial (0x1018)
    coupler: str | None = None  # TwinCAT name of the coupler it hangs off
    position: int = 0  # bus order, 0-based
    type_name: str = ""  # TwinCAT's type of the slave (master CoE 0x8000+n:02)
    al_state: int = 0  # raw AL state byte at discovery (0x08 = OP)
    link_state: int = 0  # raw link-state byte at discovery (0 = fine)
    is_coupler: bool = False  # starts a segment (EK1100, EK1122, ...)


@dataclass(slots=True)
class TerminalPlan:
    """A slave, the YAML it matched (if any) and the points it serves."""

    slave: SlaveInfo
    terminal_type: str | None  # YAML type name; None: unknown -> generic
    exact_revision: bool = True
    active_group: str | None = None  # detected from the live symbols
    oversampling: int | None = None  # samples per cycle in the live table
    points: list[Point] = field(default_factory=list)
    coe: list[CoePoint] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    poll_rate_hz: float | None = None  # per-terminal override


@dataclass(slots=True)
class MasterPlan:
    """One EtherCAT master (an I/O device of type EtherCAT) and its terminals."""

    device_id: int
    name: str  # "Device 1 (EtherCAT)"
    net_id: str  # the master's own AMS NetId, "a.b.c.d.e.f"
    symbol_port: int  # the device's ADS port for symbols and sum reads (27905)
    terminals: list[TerminalPlan] = field(default_factory=list)
    master_points: list[Point] = field(default_factory=list)  # Inputs.*, Outputs.*


@dataclass(slots=True)
class SystemPlan:
    """Everything discovery found on one target."""

    net_id: str
    device_name: str
    device_version: str
    symbol_version: int
    masters: list[MasterPlan] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    offline_from: str = ""
    """Where a plan made without the target came from (a chain file, the
    cache); "" for a plan discovered on the live target."""
