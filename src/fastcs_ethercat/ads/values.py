"""TwinCAT values by type name: sizes, numpy dtypes, pack and unpack.

Covers the scalar types of the I/O image and PLC (BOOL, BIT, BIT2..BIT8,
SINT/USINT/BYTE, INT/UINT/WORD, DINT/UDINT/DWORD, LINT/ULINT/LWORD, REAL,
LREAL, TIME-like 32/64-bit types), STRING(n) (n + 1 bytes, Windows-1252,
NUL-terminated), WSTRING(n) and `ARRAY [a..b(, c..d)] OF T`. Every type has a
numpy dtype so a whole sum-read answer can be viewed at once on the hot
path (`ads.sums.SumReadLayout.dtype`).

BIT and BITn fields live in the bit image; read by bytes (as pyads does, with
a 1-byte BOOL) they occupy one byte each.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Final

import numpy as np

from fastcs_ethercat.ads.constants import AdsDataType, AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.wire import STRING_ENCODING

DEFAULT_STRING_LENGTH: Final = 80
"""STRING without a length is STRING(80) in TwinCAT."""


def _fail(message: str) -> AdsCodecError:
    return AdsCodecError(message, AdsReturnCode.DEVICE_INVALID_DATA)


@dataclass(frozen=True, slots=True)
class _Scalar:
    ads_type: AdsDataType
    dtype: str
    kind: str  # "bool", "bits", "int", "float"
    bits: int = 0


_SCALARS: Final[dict[str, _Scalar]] = {
    "BOOL": _Scalar(AdsDataType.BIT, "u1", "bool"),
    "BIT": _Scalar(AdsDataType.BIT, "u1", "bool"),
    **{f"BIT{n}": _Scalar(AdsDataType.UINT8, "u1", "bits", n) for n in range(2, 9)},
    "SINT": _Scalar(AdsDataType.INT8, "i1", "int"),
    "USINT": _Scalar(AdsDataType.UINT8, "u1", "int"),
    "BYTE": _Scalar(AdsDataType.UINT8, "u1", "int"),
    "INT": _Scalar(AdsDataType.INT16, "<i2", "int"),
    "UINT": _Scalar(AdsDataType.UINT16, "<u2", "int"),
    "WORD": _Scalar(AdsDataType.UINT16, "<u2", "int"),
    "DINT": _Scalar(AdsDataType.INT32, "<i4", "int"),
    "UDINT": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "DWORD": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "TIME": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "TIME_OF_DAY": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "TOD": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "DATE": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "DATE_AND_TIME": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "DT": _Scalar(AdsDataType.UINT32, "<u4", "int"),
    "LINT": _Scalar(AdsDataType.INT64, "<i8", "int"),
    "ULINT": _Scalar(AdsDataType.UINT64, "<u8", "int"),
    "LWORD": _Scalar(AdsDataType.UINT64, "<u8", "int"),
    "LTIME": _Scalar(AdsDataType.UINT64, "<u8", "int"),
    "REAL": _Scalar(AdsDataType.REAL32, "<f4", "float"),
    "LREAL": _Scalar(AdsDataType.REAL64, "<f8", "float"),
}

_STRING = re.compile(r"^(W?STRING)\s*(?:[\(\[]\s*(\d+)\s*[\)\]])?$", re.IGNORECASE)
_ARRAY = re.compile(
    r"^ARRAY\s*\[(?P<dims>[^\]]*)\]\s*OF\s+(?P<element>.+)$", re.IGNORECASE
)
_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")


@dataclass(frozen=True, slots=True)
class TwinCatType:
    """A parsed TwinCAT type name with everything needed to move its bytes."""

    name: str
    ads_type: AdsDataType
    size: int
    dtype: np.dtype[Any]
    kind: str
    """"bool", "bits", "int", "float", "string", "wstring" or "array"."""
    bits: int = 0
    string_length: int = 0
    element: TwinCatType | None = None
    shape: tuple[int, ...] = ()
    lower_bounds: tuple[int, ...] = ()

    def pack(self, value: Any) -> bytes:
        """The value's bytes (little-endian, exactly `size` long)."""
        try:
            return self._pack(value)
        except AdsCodecError:
            raise
        except (TypeError, ValueError, OverflowError) as error:
            raise _fail(f"cannot pack {value!r} as {self.name}: {error}") from error

    def _pack(self, value: Any) -> bytes:
        if self.kind == "bool":
            return b"\x01" if bool(value) else b"\x00"
        if self.kind == "bits":
            number = int(value)
            if not 0 <= number < (1 << self.bits):
                raise _fail(f"{number} does not fit {self.name}")
            return bytes([number])
        if self.kind == "int":
            info = np.iinfo(self.dtype)
            if isinstance(value, float) and not value.is_integer():
                raise _fail(f"{value} is not a whole number for {self.name}")
            number = int(value)
            if not info.min <= number <= info.max:
                raise _fail(f"{number} out of range for {self.name}")
            return np.array(number, dtype=self.dtype).tobytes()
        if self.kind == "float":
            return np.array(float(value), dtype=self.dtype).tobytes()
        if self.kind == "string":
            raw = str(value).encode(STRING_ENCODING)
            if len(raw) > self.string_length:
                raise _fail(f"{len(raw)} characters do not fit {self.name}")
            return raw.ljust(self.size, b"\0")
        if self.kind == "wstring":
            raw = str(value).encode("utf-16-le")
            if len(raw) > 2 * self.string_length:
                raise _fail(f"{len(raw) // 2} characters do not fit {self.name}")
            return raw.ljust(self.size, b"\0")
        return self._pack_array(value)

    def _pack_array(self, value: Any) -> bytes:
        element = self.element
        assert element is not None
        count = int(np.prod(self.shape))
        flat = _flatten(value)
        if len(flat) != count:
            raise _fail(f"{self.name} needs {count} elements, got {len(flat)}")
        return b"".join(element.pack(item) for item in flat)

    def unpack(self, raw: bytes | bytearray | memoryview) -> Any:
        """The Python value of exactly `size` bytes."""
        data = bytes(raw)
        if len(data) != self.size:
            raise AdsCodecError(
                f"{self.name} is {self.size} bytes, got {len(data)}",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        if self.kind == "bool":
            return data[0] != 0
        if self.kind == "bits":
            return data[0] & ((1 << self.bits) - 1)
        if self.kind == "int":
            return int(np.frombuffer(data, dtype=self.dtype)[0])
        if self.kind == "float":
            return float(np.frombuffer(data, dtype=self.dtype)[0])
        if self.kind == "string":
            return data.split(b"\0", 1)[0].decode(STRING_ENCODING, errors="replace")
        if self.kind == "wstring":
            end = next(
                (i for i in range(0, len(data) - 1, 2) if data[i : i + 2] == b"\0\0"),
                len(data) - len(data) % 2,
            )
            return data[:end].decode("utf-16-le", errors="replace")
        element = self.element
        assert element is not None
        items = [
            element.unpack(data[i : i + element.size])
            for i in range(0, len(data), element.size)
        ]
        return _nest(items, self.shape)


def _flatten(value: Any) -> list[Any]:
    if isinstance(value, str | bytes):
        return [value]
    if isinstance(value, np.ndarray):
        return list(value.reshape(-1).tolist())
    if isinstance(value, Sequence):
        flat: list[Any] = []
        for item in value:
            flat.extend(_flatten(item) if _is_nested(item) else [item])
        return flat
    return [value]


def _is_nested(item: Any) -> bool:
    return isinstance(item, Sequence | np.ndarray) and not isinstance(item, str | bytes)


def _nest(items: list[Any], shape: tuple[int, ...]) -> list[Any]:
    if len(shape) <= 1:
        return items
    step = len(items) // shape[0]
    return [_nest(items[i : i + step], shape[1:]) for i in range(0, len(items), step)]


@lru_cache(maxsize=4096)
def parse_type(type_name: str) -> TwinCatType:
    """Parse a TwinCAT type name ("INT", "STRING(20)", "ARRAY [1..4] OF REAL")."""
    text = " ".join(type_name.split())
    upper = text.upper()
    if upper in _SCALARS:
        scalar = _SCALARS[upper]
        dtype = np.dtype(scalar.dtype)
        return TwinCatType(
            upper, scalar.ads_type, dtype.itemsize, dtype, scalar.kind, scalar.bits
        )
    if match := _STRING.match(text):
        wide = match.group(1).upper() == "WSTRING"
        length = int(match.group(2) or DEFAULT_STRING_LENGTH)
        width = 2 if wide else 1
        size = width * (length + 1)
        return TwinCatType(
            f"{'WSTRING' if wide else 'STRING'}({length})",
            AdsDataType.WSTRING if wide else AdsDataType.STRING,
            size,
            np.dtype(f"V{size}") if wide else np.dtype(f"S{size}"),
            "wstring" if wide else "string",
            string_length=length,
        )
    if match := _ARRAY.match(text):
        element = parse_type(match.group("element"))
        lower: list[int] = []
        shape: list[int] = []
        for part in match.group("dims").split(","):
            bounds = _RANGE.match(part)
            if bounds is None:
                raise _fail(f"bad array range {part.strip()!r} in {type_name!r}")
            low, high = int(bounds.group(1)), int(bounds.group(2))
            if high < low:
                raise _fail(f"empty array range {low}..{high} in {type_name!r}")
            lower.append(low)
            shape.append(high - low + 1)
        ranges = ", ".join(
            f"{lo}..{lo + n - 1}" for lo, n in zip(lower, shape, strict=True)
        )
        count = int(np.prod(shape))
        return TwinCatType(
            f"ARRAY [{ranges}] OF {element.name}",
            element.ads_type,
            element.size * count,
            np.dtype((element.dtype, tuple(shape))),
            "array",
            element=element,
            shape=tuple(shape),
            lower_bounds=tuple(lower),
        )
    raise _fail(f"unknown TwinCAT type {type_name!r}")


def pack_value(type_name: str, value: Any) -> bytes:
    """Bytes of `value` as TwinCAT type `type_name`."""
    return parse_type(type_name).pack(value)


def unpack_value(type_name: str, raw: bytes | bytearray | memoryview) -> Any:
    """Python value of `raw` as TwinCAT type `type_name`."""
    return parse_type(type_name).unpack(raw)


def array_type_name(lower: int, upper: int, element: str) -> str:
    """TwinCAT's spelling of a one-dimensional array type."""
    return f"ARRAY [{lower}..{upper}] OF {element}"


def structured_dtype(
    fields: Sequence[tuple[str, np.dtype[Any] | str, int]], itemsize: int | None = None
) -> np.dtype[Any]:
    """A numpy structured dtype from (name, dtype, byte offset) triples."""
    names = [name for name, _, _ in fields]
    formats = [np.dtype(dtype) for _, dtype, _ in fields]
    offsets = [offset for _, _, offset in fields]
    end = max(
        (o + f.itemsize for o, f in zip(offsets, formats, strict=True)), default=0
    )
    return np.dtype(
        {
            "names": names,
            "formats": formats,
            "offsets": offsets,
            "itemsize": max(end, itemsize or 0),
        }
    )
