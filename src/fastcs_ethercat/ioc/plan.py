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

from fastcs_ethercat.terminals.meaning import Scaling


class PointKind(Enum):
    """How a point's value sits in the bytes of its symbol."""

    SCALAR = "scalar"  # a whole number/float/bool/string of `type_name`
    BIT = "bit"  # one bit: `bit_offset` within the read bytes
    BITS = "bits"  # an unsigned field of `bit_size` bits at `bit_offset`
    ARRAY = "array"  # `length` elements of `type_name` (oversampling samples)


@dataclass(frozen=True, slots=True)
class Point:
    """One value the IOC serves: a TwinCAT symbol or one member of it.

    `index_group`/`index_offset`/`byte_size` are what a sum read asks for (the
    live table's address of the symbol, moved to the member's byte); for BIT
    points in the bit-addressed image groups the size is 1 byte and
    `bit_offset` says which bit.
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


@dataclass(frozen=True, slots=True)
class SlaveInfo:
    """One EtherCAT slave as the master reports it."""

    address: int  # EtherCAT address, 1001, 1002, ...
    name: str  # TwinCAT name, "Term 5 (EL3104)"
    vendor_id: int
    product_code: int
    revision: int
    serial: int = 0
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
