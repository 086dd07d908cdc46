"""Plan points -> FastCS attributes, and the IO that writes them back.

A `Point` (a TwinCAT symbol or one member of it) becomes an `AttrR` (inputs)
or an `AttrRW` (outputs, RxPDO symbols); its values arrive from the poller,
which pushes only changed values, so a point attribute has no periodic update
of its own. Writes go through `PointIO` to a writer the app supplies (the
poller's `write_point`). A `CoePoint` becomes an attribute read once at start
(and again on demand) and written through `CoeIO` as an SDO.

A point whose value has engineering units (`Point.scaling`) is served in
them, and its raw count by a read-only twin (`raw_twin`) that `Health` feeds
with every value of the point (`Health.follow`). A status bit's severity
rides on its datatype (`datatypes.AlarmBool`, `AlarmInt`).

A point whose type cannot be served never disappears silently: it is returned
with its reason by `attribute_for_point`'s callers and reported.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Awaitable, Callable
from dataclasses import KW_ONLY, dataclass
from typing import Any

import numpy as np
from fastcs.attributes import Attribute, AttributeIO, AttributeIORef, AttrR, AttrRW
from fastcs.attributes.attr_w import AttrW
from fastcs.datatypes import Bool, DataType, Enum, Float, Int, Waveform

from fastcs_ethercat.ads.values import parse_type
from fastcs_ethercat.ioc.datatypes import (
    AlarmBool,
    AlarmInt,
    description,
    engineering,
    enum_class,
    to_fastcs,
)
from fastcs_ethercat.ioc.plan import CoePoint, Point, PointKind
from fastcs_ethercat.terminals.meaning import Scaling, has_raw_twin

PointWriter = Callable[[Point, Any], Awaitable[None]]
"""Writes one value of an output point to the target (the poller's write_point)."""
CoeReader = Callable[[CoePoint], Awaitable[Any]]
CoeWriter = Callable[[CoePoint, Any], Awaitable[None]]


def point_datatype(point: Point) -> DataType:
    """The FastCS datatype of a point: width, signedness, enum, waveform, the
    engineering units it is served in, the severity of a status bit.

    Raises `UnsupportedTypeError` (a `ValueError`) for a type with no PV form.
    """
    members = dict(point.enum_texts) if point.enum_texts else None
    if point.kind is PointKind.BIT:
        return AlarmBool(severities=(0, point.severity)) if point.severity else Bool()
    if point.kind is PointKind.BITS:
        if members is not None:
            return Enum(enum_class(point.attribute, members))
        top = (1 << max(point.bit_size, 1)) - 1
        if point.severity:
            return AlarmInt(min=0, max=top, set_severity=point.severity)
        return Int(min=0, max=top)
    scaling = point.scaling
    if point.kind is PointKind.ARRAY:
        length = max(point.length, 1)
        if has_raw_twin(scaling):
            return Waveform(np.dtype(np.float64), shape=(length,))
        return to_fastcs(f"ARRAY [0..{length - 1}] OF {point.type_name}")
    if scaling is not None and members is None:
        return engineering(point.type_name, scaling)
    datatype = to_fastcs(
        point.type_name, enum_members=members, enum_name=point.attribute
    )
    if point.severity and type(datatype) is Int:  # a status word (Frm0WcState)
        return AlarmInt(min=datatype.min, max=datatype.max, set_severity=point.severity)
    return datatype


def converts(point: Point) -> bool:
    """Whether the point's value is served scaled (and its raw count by a twin)."""
    return has_raw_twin(point.scaling)


def raw_twin(point: Point) -> AttrR[Any, Any] | None:
    """The read-only attribute of a scaled point's raw count; None when the
    point is served unscaled."""
    if not converts(point):
        return None
    raw = dataclasses.replace(point, scaling=None)
    return AttrR(
        point_datatype(raw),
        io_ref=PointRef(raw),
        description=description(_raw_description(point.description)),
    )


def _raw_description(text: str) -> str:
    mark = " raw"
    return text[: 40 - len(mark)].rstrip() + mark if text else "raw count"


def to_engineering(scaling: Scaling) -> Callable[[Any], Any]:
    """raw count (int, float or array) -> engineering value."""
    scale, offset = scaling.scale, scaling.offset

    def convert(raw: Any) -> Any:
        return raw * scale + offset

    return convert


def engineering_value(point: Point, raw: Any) -> Any:
    """A count the device takes as the point's PV shows it (what a write's
    setpoint shows: the count written, not the value asked for)."""
    scaling = point.scaling
    if scaling is None or not has_raw_twin(scaling):
        return raw
    return to_engineering(scaling)(np.asarray(raw) if isinstance(raw, list) else raw)


def from_engineering(point: Point, value: Any) -> Any:
    """An engineering value as the count the device takes: the nearest count
    for an integer type (outside its range, the write is refused)."""
    scaling = point.scaling
    if scaling is None or not has_raw_twin(scaling):
        return value
    raw = (np.asarray(value, dtype=np.float64) - scaling.offset) / scaling.scale
    if parse_type(point.type_name).kind in ("int", "bits"):
        raw = np.rint(raw).astype(np.int64)
    return raw.tolist()


def coe_datatype(coe: CoePoint) -> DataType:
    """The FastCS datatype of a CoE sub-item (its ESI type, enum texts, the
    unit of a number)."""
    if coe.enum_texts:  # ESI enum types (DT0800EN03) name no base type
        return Enum(enum_class(coe.attribute, dict(coe.enum_texts)))
    try:
        datatype = to_fastcs(coe.type_name)
    except ValueError:
        if coe.bit_size == 1:
            return Bool()
        if 0 < coe.bit_size <= 16:
            return Int(min=0, max=(1 << coe.bit_size) - 1)
        raise
    if coe.units and isinstance(datatype, Int | Float):
        return dataclasses.replace(datatype, units=coe.units)
    return datatype


def to_device(value: Any) -> Any:
    """A FastCS value as the data plane writes it: enums as their number."""
    if isinstance(value, enum.Enum):
        return int(value.value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


@dataclass
class PointRef(AttributeIORef):
    """The point an attribute serves; updated by the poller, never scanned."""

    point: Point
    _: KW_ONLY
    update_period: float | None = None


class PointIO(AttributeIO[Any, PointRef]):
    """Writes of output points: hand the value to the data plane's writer."""

    def __init__(self, writer: PointWriter) -> None:
        super().__init__()
        self.writer = writer

    async def send(self, attr: AttrW[Any, PointRef], value: Any) -> None:
        point = attr.io_ref.point
        await self.writer(point, from_engineering(point, to_device(value)))


@dataclass
class CoeRef(AttributeIORef):
    """The CoE object sub-item an attribute serves: read by its terminal once
    the IOC serves (not by FastCS before: see `app.start_supervising`)."""

    coe: CoePoint
    _: KW_ONLY
    update_period: float | None = None


class CoeIO(AttributeIO[Any, CoeRef]):
    """SDO access of one terminal's CoE attributes.

    A failed read leaves the value as it was and is logged by FastCS; it never
    raises out of `update`, so one unreachable object does not pause the tree.
    """

    def __init__(self, reader: CoeReader, writer: CoeWriter) -> None:
        super().__init__()
        self.reader = reader
        self.writer = writer
        self.failures: dict[str, str] = {}
        self.read_back: Callable[[AttrR[Any, Any]], Awaitable[None]] | None = None
        """How its terminal reads and posts a value (alarms, timestamps); the
        plain FastCS update until a terminal controller sets it."""

    async def update(self, attr: AttrR[Any, CoeRef]) -> None:
        if self.read_back is not None:
            await self.read_back(attr)
            return
        coe = attr.io_ref.coe
        try:
            await attr.update(await self.reader(coe))
            self.failures.pop(coe.attribute, None)
        except Exception as error:  # one object must not stop the tree
            self.failures[coe.attribute] = f"{type(error).__name__}: {error}"

    async def send(self, attr: AttrW[Any, CoeRef], value: Any) -> None:
        """Write the SDO, then read it back so the readback shows the slave's."""
        await self.writer(attr.io_ref.coe, to_device(value))
        if isinstance(attr, AttrR):
            await self.update(attr)


READ_ONLY_MARK = "(read-only) "
"""Starts the description (DESC) of an output the IOC serves read-only
(`--read-only`), so a client sees why it cannot write it."""


def _described(text: str, writable: bool, read_only: bool) -> str | None:
    return description(READ_ONLY_MARK + text if writable and read_only else text)


def attribute_for_point(point: Point, *, read_only: bool = False) -> Attribute:
    """An `AttrRW` for a writable point (unless read-only), else an `AttrR`."""
    datatype = point_datatype(point)
    text = _described(point.description or point.symbol, point.writable, read_only)
    if point.writable and not read_only:
        return AttrRW(datatype, io_ref=PointRef(point), description=text)
    return AttrR(datatype, io_ref=PointRef(point), description=text)


def attribute_for_coe(coe: CoePoint, *, read_only: bool = False) -> Attribute:
    """An attribute for a CoE sub-item, read at start and written as an SDO."""
    datatype = coe_datatype(coe)
    text = _described(
        coe.description or f"CoE {coe.index:04X}:{coe.subindex:02X} {coe.attribute}",
        coe.writable,
        read_only,
    )
    if coe.writable and not read_only:
        return AttrRW(datatype, io_ref=CoeRef(coe), description=text)
    return AttrR(datatype, io_ref=CoeRef(coe), description=text)


def from_device(attr: AttrR[Any, Any], value: Any) -> Any:
    """A data-plane value in the form the attribute's datatype validates."""
    enum_cls = enum_of(attr)
    if enum_cls is not None and not isinstance(value, enum.Enum):
        return enum_cls(int(value))
    return value


def enum_of(attr: AttrR[Any, Any]) -> Any:
    """The enum an attribute's values are members of (None: not an enum):
    the only data-plane values `from_device` converts."""
    datatype = attr.datatype
    return datatype.enum_cls if isinstance(datatype, Enum) else None
