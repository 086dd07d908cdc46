"""The bytes of a write: a value checked against its point's TwinCAT type,
then packed the way its symbol handle takes it (`ioc/decode.py` is the
read side).

A value the type cannot hold is refused here, before ADS, with the point's
name (`ValueError`): the client's put fails with that reason.
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np

from fastcs_ethercat.ads.values import array_type_name, pack_value
from fastcs_ethercat.ioc.plan import Point, PointKind

INTEGER_RANGES: Final = {
    "SINT": (-(2**7), 2**7 - 1),
    "USINT": (0, 2**8 - 1),
    "BYTE": (0, 2**8 - 1),
    "INT": (-(2**15), 2**15 - 1),
    "UINT": (0, 2**16 - 1),
    "WORD": (0, 2**16 - 1),
    "DINT": (-(2**31), 2**31 - 1),
    "UDINT": (0, 2**32 - 1),
    "DWORD": (0, 2**32 - 1),
    "LINT": (-(2**63), 2**63 - 1),
    "ULINT": (0, 2**64 - 1),
    "LWORD": (0, 2**64 - 1),
}
REAL_MAX: Final = 3.4028234663852886e38


def check_write(point: Point, value: Any) -> None:
    """Refuse (ValueError) a value the point's type cannot hold, before ADS."""
    if point.kind is PointKind.ARRAY:
        values = list(value) if isinstance(value, list | tuple) else None
        if values is None or len(values) != point.length:
            raise ValueError(f"{point.symbol} takes {point.length} values")
        for element in values:
            _check_scalar(point, point.type_name, element)
        return
    if point.kind is PointKind.BIT or point.type_name in ("BOOL", "BIT"):
        if value not in (0, 1) or isinstance(value, float):
            raise ValueError(f"{value!r} is not a boolean for {point.symbol}")
        return
    if point.kind is PointKind.BITS:
        bits = max(point.bit_size, 1)
        if not isinstance(value, int) or not 0 <= value < 1 << bits:
            raise ValueError(f"{value!r} does not fit {bits} bits of {point.symbol}")
        return
    _check_scalar(point, point.type_name, value)


def _check_scalar(point: Point, type_name: str, value: Any) -> None:
    limits = INTEGER_RANGES.get(type_name)
    if limits is not None:
        integral = isinstance(value, int | np.integer) or (
            isinstance(value, float) and value.is_integer()
        )
        if isinstance(value, bool) or not integral:
            raise ValueError(f"{value!r} is not an integer for {point.symbol}")
        low, high = limits
        if not low <= int(value) <= high:
            raise ValueError(
                f"{value!r} is out of range {low}..{high} ({type_name}) "
                f"for {point.symbol}"
            )
    elif type_name in ("REAL", "LREAL"):
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise ValueError(f"{value!r} is not a number for {point.symbol}")
        if not math.isfinite(float(value)):
            raise ValueError(f"{value!r} is not finite for {point.symbol}")
        if type_name == "REAL" and abs(float(value)) > REAL_MAX:
            raise ValueError(f"{value!r} is out of range of REAL for {point.symbol}")


def pack_write(point: Point, value: Any) -> bytes:
    """The bytes a write of `value` to `point`'s handle takes (ValueError if
    its type cannot hold it): a bit or bit field one byte holding the value,
    which the target puts into those bits alone; an oversampling array all
    its elements."""
    check_write(point, value)
    if point.kind in (PointKind.BIT, PointKind.BITS):
        bits = max(point.bit_size, 1)
        number = int(bool(value)) if bits == 1 else int(value)
        return number.to_bytes((bits + 7) // 8, "little")
    type_name = point.type_name
    if point.kind is PointKind.ARRAY:
        type_name = array_type_name(0, point.length - 1, point.type_name)
    return pack_value(type_name, value)
