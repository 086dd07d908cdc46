"""TwinCAT / ESI type names -> FastCS datatypes, with units and value ranges.

Type names are parsed by the codec (`ads.values.parse_type`), which also gives
the numpy dtype of the bytes; this module only decides the FastCS side.

What FastCS 0.14.4 does with them decides the mapping:

- `Int` becomes a 32-bit `longin`/`longout` record (CA) and an `i` NTScalar
  (PVA). A value beyond int32 is silently wrapped by both (2**31 + 5 reads
  back as -2147483643), so only SINT, USINT, INT, UINT and DINT are `Int`.
- UDINT/DWORD and LINT/ULINT/LWORD become `IntegralFloat`: an EPICS double,
  which holds every UDINT exactly and 64-bit values exactly up to 2**53.
- `Float.validate` rounds to `prec` decimals, so a plain `Float()` stores 1.23
  for 1.23456789. REAL/LREAL become `ExactFloat`, which keeps every bit and
  uses `prec` for display (PREC, PVA display.precision, screens) only.
- `min`/`max` of `Int`/`Float` become DRVL/DRVH on CA outputs (EPICS clamps an
  out-of-range caput) and reject an out-of-range PVA put.
- Enums with up to 16 members become mbbi/mbbo (state strings of at most 25
  characters), longer ones long-string records.

Two additions of this project:

- **Engineering units** (`engineering`): a scaled value is an `ExactFloat`
  in its unit (EGU) with its precision (PREC) and the range of its raw type
  converted (PVA display limits, DRVL/DRVH of an output).
- **States that are alarms** (`AlarmBool`, `AlarmInt`, `AlarmEnum`): the
  severity of each value is part of the datatype, a lookup in a table made
  once (`alarm_severity(value)`), so publishing a value costs one index.
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Final, Protocol, TypeVar, cast

import numpy as np
from fastcs.datatypes import Bool, DataType, Enum, Float, Int, String, Waveform

from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.values import TwinCatType, parse_type
from fastcs_ethercat.terminals.meaning import Scaling

MAX_ENUM_LABEL_LENGTH: Final = 25
"""mbbi/mbbo state strings (ZRST ...) hold 25 bytes plus NUL; softioc refuses
longer ones with an AssertionError, which stops the IOC from starting."""
MAX_DESCRIPTION_LENGTH: Final = 40
"""A record's DESC holds 40 bytes; a longer attribute description stops the
IOC from starting (softioc asserts), so descriptions go through `description`."""
EXACT_DOUBLE_INTEGER: Final = 2**53
"""Integers up to this magnitude survive the trip through an EPICS double."""
MBB_MAX_STATES: Final = 16
"""FastCS serves an enum of more members as a long string, not an mbbi/mbbo."""


class UnsupportedTypeError(ValueError):
    """A type name this IOC cannot serve as a PV."""


@dataclass(frozen=True)
class ExactFloat(Float):
    """A `Float` that never rounds the value; `prec` is for display only."""

    def validate(self, value: Any) -> float:
        return super(Float, self).validate(value)


@dataclass(frozen=True)
class IntegralFloat(ExactFloat):
    """An integer carried as an EPICS double (UDINT, LINT, ULINT).

    Accepts only whole numbers within `min`..`max`; whole numbers beyond 2**53
    lose their lowest bits in the double.
    """

    prec: int = 0

    def validate(self, value: Any) -> float:
        number = super().validate(value)
        if not math.isfinite(number) or not number.is_integer():
            raise ValueError(f"Value {value!r} is not a whole number")
        return number


_DISPLAY_PRECISION: Final = {"REAL": 6, "LREAL": 9}
E = TypeVar("E", bound=enum.Enum)


# -- states that are alarms -----------------------------------------------------


class ValueAlarms(Protocol):
    """A datatype whose values carry an EPICS alarm severity of their own."""

    def alarm_severity(self, value: Any) -> int:
        """0 (NO_ALARM), 1 (MINOR), 2 (MAJOR) or 3 (INVALID) for `value`."""
        ...


def has_value_alarms(datatype: DataType) -> bool:
    """Whether `datatype` is a `ValueAlarms`: looked up on its class, as a
    runtime-checkable protocol would, without that check's ~100 µs a call
    (once per attribute at start)."""
    return callable(getattr(type(datatype), "alarm_severity", None))


def severity_table(datatype: DataType) -> Any:
    """`datatype.alarm_severity`, or None for a datatype without alarms."""
    if not has_value_alarms(datatype):
        return None
    return cast(ValueAlarms, datatype).alarm_severity


@dataclass(frozen=True)
class AlarmBool(Bool):
    """A bit whose two states carry severities: (when False, when True)."""

    severities: tuple[int, int] = (0, 0)

    def alarm_severity(self, value: Any) -> int:
        return self.severities[1 if value else 0]


@dataclass(frozen=True)
class AlarmInt(Int):
    """A bit field (`Limit 1`) with a severity while it is not zero."""

    set_severity: int = 0

    def alarm_severity(self, value: Any) -> int:
        return self.set_severity if value else 0


@dataclass(frozen=True)
class AlarmEnum(Enum[Any]):
    """An enum whose members carry severities, in member order (mbbi's
    ZRSV, ONSV ... as a table)."""

    severities: tuple[int, ...] = ()

    @cached_property
    def _by_member(self) -> dict[Any, int]:
        return dict(zip(self.members, self.severities, strict=False))

    def alarm_severity(self, value: Any) -> int:
        return self._by_member.get(value, 0)


def type_label(datatype: DataType) -> str:
    """The datatype's name for PV lists: an alarm state is listed as the
    FastCS type it is (`AlarmBool` -> `Bool`)."""
    kind = type(datatype)
    if has_value_alarms(datatype):
        kind = kind.__mro__[1]
    return kind.__name__


def ca_record_type(datatype: DataType, *, output: bool = False) -> str:
    """The EPICS record FastCS serves `datatype` as on CA: its in record, or
    with `output` the out record of a writable PV. Texts, enums of more than
    `MBB_MAX_STATES` members and arrays are softioc waveforms."""
    match datatype:
        case Bool():
            return "bo" if output else "bi"
        case Int():
            return "longout" if output else "longin"
        case Float():
            return "ao" if output else "ai"
        case Enum() if len(datatype.members) <= MBB_MAX_STATES:
            return "mbbo" if output else "mbbi"
        case _:
            return "waveform"


def alarm_enum(enum_cls: type[E], severities: Mapping[E, int]) -> AlarmEnum:
    """An `AlarmEnum` of `enum_cls` with a severity per member (0 if unnamed)."""
    return AlarmEnum(enum_cls, tuple(severities.get(m, 0) for m in enum_cls))


# -- engineering units ----------------------------------------------------------


def engineering(type_name: str, scaling: Scaling) -> DataType:
    """The datatype of a value of `type_name` served as `scaling` says: in
    its unit with its precision, converted to a float where it converts."""
    try:
        parsed = parse_type(type_name)
    except AdsCodecError as error:
        raise UnsupportedTypeError(str(error)) from None
    if parsed.kind not in ("int", "bits", "float"):
        raise UnsupportedTypeError(f"no engineering units for {type_name}")
    units = scaling.unit or None
    if not scaling.converts:
        return to_fastcs(type_name, units=units, precision=scaling.precision)
    if parsed.kind == "float":
        return ExactFloat(units=units, prec=scaling.decimals)
    ends = [count * scaling.scale + scaling.offset for count in integer_range(parsed)]
    return ExactFloat(units=units, prec=scaling.decimals, min=min(ends), max=max(ends))


def to_fastcs(
    type_name: str,
    *,
    units: str | None = None,
    enum_members: Mapping[int, str] | None = None,
    enum_name: str | None = None,
    precision: int | None = None,
) -> DataType:
    """The FastCS datatype of a TwinCAT type, with units and value range.

    `enum_members` (value -> label, e.g. from an ESI EnumInfo) turns an
    integer type into an `Enum`.
    """
    try:
        parsed = parse_type(type_name)
    except AdsCodecError as error:
        raise UnsupportedTypeError(str(error)) from None
    if enum_members is not None:
        if parsed.kind not in ("int", "bits"):
            raise UnsupportedTypeError(
                f"an enum needs an integer base, not {type_name}"
            )
        return Enum(enum_class(enum_name or type_name, enum_members))
    if parsed.kind in ("string", "wstring"):
        return String(length=parsed.string_length)
    if parsed.kind == "array":
        element = parsed.element
        if element is None or element.kind not in ("bool", "bits", "int", "float"):
            raise UnsupportedTypeError(f"no waveform for {type_name}")
        if len(parsed.shape) != 1:
            raise UnsupportedTypeError(f"only one-dimensional arrays: {type_name}")
        return Waveform(element.dtype.newbyteorder("="), shape=parsed.shape)
    if parsed.kind == "bool":
        return Bool()
    if parsed.kind == "float":
        return ExactFloat(
            units=units, prec=_precision(precision, _DISPLAY_PRECISION[parsed.name])
        )
    low, high = integer_range(parsed)
    if high <= 2**31 - 1:
        return Int(units=units, min=low, max=high)
    return IntegralFloat(units=units, min=float(low), max=float(high))


def integer_range(parsed: TwinCatType) -> tuple[int, int]:
    """Smallest and largest value of an integer (or BITn) type."""
    if parsed.kind == "bits":
        return 0, (1 << parsed.bits) - 1
    info = np.iinfo(parsed.dtype)
    return int(info.min), int(info.max)


def enum_class(name: str, members: Mapping[int, str]) -> type[enum.IntEnum]:
    """An IntEnum of the members sorted by value, labels fit for mbb records.

    Labels are cut to 25 characters; a label that repeats gets its value
    appended, so every member keeps its own name.
    """
    if not members:
        raise UnsupportedTypeError(f"enum {name!r} has no members")
    labels: dict[str, int] = {}
    for value in sorted(members):
        label = _fit(members[value], MAX_ENUM_LABEL_LENGTH) or str(value)
        if label in labels:
            suffix = f" {value}"
            label = _fit(label, MAX_ENUM_LABEL_LENGTH - len(suffix)) + suffix
        labels[label] = value
    return enum.IntEnum(_class_name(name), labels)  # type: ignore[return-value]


def description(text: str | None) -> str | None:
    """An attribute description that fits a record's DESC (40 bytes)."""
    if text is None:
        return None
    return _fit(text, MAX_DESCRIPTION_LENGTH) or None


def _fit(text: str, limit: int) -> str:
    """`text` with whitespace collapsed, cut to at most `limit` UTF-8 bytes."""
    cut = " ".join(text.split()).encode("utf-8")[:limit]
    return cut.decode("utf-8", errors="ignore").rstrip()


def _precision(requested: int | None, default: int) -> int:
    return default if requested is None else requested


def _class_name(name: str) -> str:
    cleaned = re.sub(r"\W", "_", name).strip("_") or "Enum"
    return cleaned if cleaned[0].isalpha() else f"E{cleaned}"
