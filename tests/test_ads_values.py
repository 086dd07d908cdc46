"""TwinCAT values by type name: sizes, dtypes, pack/unpack, pyads agreement."""

from __future__ import annotations

import contextlib
import ctypes
import math
from typing import Any

import numpy as np
import pyads
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fastcs_ethercat.ads.constants import AdsDataType
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.values import (
    array_type_name,
    pack_value,
    parse_type,
    structured_dtype,
    unpack_value,
)

# TwinCAT type -> (pyads PLCTYPE, size, ADS type id)
PYADS_TYPES: dict[str, tuple[Any, int, AdsDataType]] = {
    "BOOL": (pyads.PLCTYPE_BOOL, 1, AdsDataType.BIT),
    "SINT": (pyads.PLCTYPE_SINT, 1, AdsDataType.INT8),
    "USINT": (pyads.PLCTYPE_USINT, 1, AdsDataType.UINT8),
    "BYTE": (pyads.PLCTYPE_BYTE, 1, AdsDataType.UINT8),
    "INT": (pyads.PLCTYPE_INT, 2, AdsDataType.INT16),
    "UINT": (pyads.PLCTYPE_UINT, 2, AdsDataType.UINT16),
    "WORD": (pyads.PLCTYPE_WORD, 2, AdsDataType.UINT16),
    "DINT": (pyads.PLCTYPE_DINT, 4, AdsDataType.INT32),
    "UDINT": (pyads.PLCTYPE_UDINT, 4, AdsDataType.UINT32),
    "DWORD": (pyads.PLCTYPE_DWORD, 4, AdsDataType.UINT32),
    "LINT": (pyads.PLCTYPE_LINT, 8, AdsDataType.INT64),
    "ULINT": (pyads.PLCTYPE_ULINT, 8, AdsDataType.UINT64),
    "REAL": (pyads.PLCTYPE_REAL, 4, AdsDataType.REAL32),
    "LREAL": (pyads.PLCTYPE_LREAL, 8, AdsDataType.REAL64),
}


@pytest.mark.parametrize("name", list(PYADS_TYPES))
def test_scalars_agree_with_pyads_ctypes(name: str) -> None:
    plc_type, size, ads_type = PYADS_TYPES[name]
    parsed = parse_type(name)
    assert parsed.size == size == ctypes.sizeof(plc_type)
    assert parsed.ads_type == ads_type
    assert parse_type(name).dtype.itemsize == size
    sample: Any = True if name == "BOOL" else (1.5 if "REAL" in name else 100)
    raw = pack_value(name, sample)
    assert bytes(plc_type(sample)) == raw
    assert unpack_value(name, raw) == sample
    assert plc_type.from_buffer_copy(raw).value == sample


def test_case_and_spacing_do_not_matter() -> None:
    assert parse_type(" int ") == parse_type("INT")
    assert parse_type("array[0..3] of int").name == "ARRAY [0..3] OF INT"


def test_bit_types() -> None:
    assert unpack_value("BIT", b"\x01") is True
    assert pack_value("BIT", 0) == b"\x00"
    assert parse_type("BIT3").size == 1
    assert pack_value("BIT3", 5) == b"\x05"
    assert unpack_value("BIT3", b"\xfd") == 5
    with pytest.raises(AdsCodecError):
        pack_value("BIT3", 8)


def test_strings() -> None:
    assert parse_type("STRING(20)").size == 21
    assert parse_type("STRING").size == 81
    assert parse_type("STRING[10]").size == 11
    raw = pack_value("STRING(5)", "Grüß")
    assert raw == "Grüß".encode("cp1252") + b"\0\0"
    assert unpack_value("STRING(5)", raw) == "Grüß"
    assert parse_type("STRING(5)").dtype == np.dtype("S6")
    with pytest.raises(AdsCodecError):
        pack_value("STRING(3)", "abcd")
    assert parse_type("WSTRING(4)").size == 10
    assert unpack_value("WSTRING(4)", pack_value("WSTRING(4)", "añb")) == "añb"


def test_arrays() -> None:
    name = array_type_name(1, 4, "INT")
    assert name == "ARRAY [1..4] OF INT"
    parsed = parse_type(name)
    assert parsed.size == 8
    assert parsed.shape == (4,)
    assert parsed.lower_bounds == (1,)
    assert parse_type(name).dtype == np.dtype(("<i2", (4,)))
    raw = pack_value(name, [1, -2, 3, -4])
    assert np.frombuffer(raw, dtype="<i2").tolist() == [1, -2, 3, -4]
    assert unpack_value(name, raw) == [1, -2, 3, -4]
    grid = "ARRAY [0..1, -1..1] OF USINT"
    assert parse_type(grid).size == 6
    assert unpack_value(grid, bytes(range(6))) == [[0, 1, 2], [3, 4, 5]]
    assert pack_value(grid, [[0, 1, 2], [3, 4, 5]]) == bytes(range(6))
    strings = "ARRAY [0..1] OF STRING(3)"
    assert unpack_value(strings, pack_value(strings, ["ab", "c"])) == ["ab", "c"]
    with pytest.raises(AdsCodecError):
        pack_value(name, [1, 2])


@pytest.mark.parametrize(
    "name", ["FOO", "ARRAY [3..1] OF INT", "ARRAY [a..b] OF INT", "ARRAY [0..1] OF FOO"]
)
def test_unknown_types(name: str) -> None:
    with pytest.raises(AdsCodecError):
        parse_type(name)


@pytest.mark.parametrize(
    ("name", "value"), [("INT", 40000), ("USINT", -1), ("UDINT", 2**32)]
)
def test_out_of_range(name: str, value: int) -> None:
    with pytest.raises(AdsCodecError):
        pack_value(name, value)


def test_wrong_size_on_unpack() -> None:
    with pytest.raises(AdsCodecError):
        unpack_value("DINT", b"\0\0")


def test_structured_dtype_views_a_process_image_struct() -> None:
    dtype = structured_dtype([("Status", "<u2", 0), ("Value", "<i2", 2)])
    raw = pack_value("UINT", 0x41) + pack_value("INT", -300)
    view = np.frombuffer(raw, dtype=dtype)[0]
    assert (int(view["Status"]), int(view["Value"])) == (0x41, -300)


integer_types = st.sampled_from(
    [
        "SINT",
        "USINT",
        "BYTE",
        "INT",
        "UINT",
        "WORD",
        "DINT",
        "UDINT",
        "DWORD",
        "LINT",
        "ULINT",
    ]
)


@given(integer_types, st.data())
def test_integer_round_trip(name: str, data: st.DataObject) -> None:
    info = np.iinfo(parse_type(name).dtype)
    value = data.draw(st.integers(int(info.min), int(info.max)))
    raw = pack_value(name, value)
    assert len(raw) == parse_type(name).size
    assert unpack_value(name, raw) == value
    assert int(np.frombuffer(raw, dtype=parse_type(name).dtype)[0]) == value


@given(st.floats(allow_nan=True, width=32))
def test_real_round_trip(value: float) -> None:
    back = unpack_value("REAL", pack_value("REAL", value))
    assert (math.isnan(back) and math.isnan(value)) or back == value


@given(
    st.sampled_from(
        [
            "BOOL",
            "BIT4",
            "INT",
            "LREAL",
            "STRING(4)",
            "WSTRING(2)",
            "ARRAY [0..2] OF UINT",
            "ARRAY [0..1] OF STRING(2)",
        ]
    ),
    st.binary(max_size=12),
)
def test_unpack_only_raises_codec_errors(name: str, raw: bytes) -> None:
    with contextlib.suppress(AdsCodecError):
        unpack_value(name, raw)
