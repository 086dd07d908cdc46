"""TwinCAT / ESI types -> FastCS datatypes: width, sign, range, precision."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastcs.datatypes import Bool, Enum, Float, Int, String, Waveform
from lxml import etree

from fastcs_ethercat.esi.dictionary import parse_data_type
from fastcs_ethercat.esi.model import EsiDataType
from fastcs_ethercat.ioc.attributes import (
    coe_datatype,
    engineering_value,
    from_engineering,
)
from fastcs_ethercat.ioc.datatypes import (
    EXACT_DOUBLE_INTEGER,
    MBB_MAX_STATES,
    AlarmBool,
    AlarmInt,
    ExactFloat,
    IntegralFloat,
    UnsupportedTypeError,
    ca_record_type,
    description,
    engineering,
    enum_class,
    to_fastcs,
    type_label,
)
from fastcs_ethercat.ioc.plan import CoePoint, Point, PointKind
from fastcs_ethercat.terminals.meaning import Scaling
from tests.conftest import ESI_SUBSET as ESI


@pytest.fixture(scope="module")
def el3104_types() -> dict[str, EsiDataType]:
    """The data types of the EL3104 in the real Beckhoff ESI file."""
    tree = etree.parse(str(ESI / "Beckhoff EL31xx.xml"))
    device = next(
        d
        for d in tree.iter("Device")
        if (d.findtext("Type") or "").startswith("EL3104")
    )
    elements = device.iterfind(".//DataTypes/DataType")
    return {t.name: t for t in (parse_data_type(e) for e in elements)}


@pytest.mark.parametrize("type_name", ["BOOL", "BIT", "bool"])
def test_bits_are_bools(type_name: str) -> None:
    assert to_fastcs(type_name) == Bool()


@pytest.mark.parametrize(
    ("type_name", "low", "high"),
    [
        ("SINT", -128, 127),
        ("USINT", 0, 255),
        ("BYTE", 0, 255),
        ("INT", -32768, 32767),
        ("UINT", 0, 65535),
        ("WORD", 0, 65535),
        ("DINT", -(2**31), 2**31 - 1),
        ("BIT2", 0, 3),
        ("BIT4", 0, 15),
    ],
)
def test_integers_up_to_32_bits_are_ints_with_their_range(
    type_name: str, low: int, high: int
) -> None:
    datatype = to_fastcs(type_name, units="counts")

    assert datatype == Int(units="counts", min=low, max=high)
    assert datatype.validate(low) == low
    assert datatype.validate(high) == high
    for outside in (low - 1, high + 1):
        with pytest.raises(ValueError):
            datatype.validate(outside)


@pytest.mark.parametrize(
    ("type_name", "low", "high", "exact"),
    [
        ("UDINT", 0, 2**32 - 1, 2**32 - 1),
        ("DWORD", 0, 2**32 - 1, 4_000_000_001),
        ("LINT", -(2**63), 2**63 - 1, -(EXACT_DOUBLE_INTEGER - 1)),
        ("ULINT", 0, 2**64 - 1, EXACT_DOUBLE_INTEGER - 1),
    ],
)
def test_wider_integers_travel_as_whole_doubles(
    type_name: str, low: int, high: int, exact: int
) -> None:
    """FastCS's Int is int32 on CA and PVA; a double holds these exactly to 2**53."""
    datatype = to_fastcs(type_name)

    assert isinstance(datatype, IntegralFloat)
    assert (datatype.min, datatype.max, datatype.prec) == (float(low), float(high), 0)
    assert int(datatype.validate(exact)) == exact
    with pytest.raises(ValueError, match="whole number"):
        datatype.validate(1.5)
    if low == 0:
        with pytest.raises(ValueError, match="less than minimum"):
            datatype.validate(-1)


@pytest.mark.parametrize(("type_name", "prec"), [("REAL", 6), ("LREAL", 9)])
def test_reals_keep_every_bit_and_use_prec_for_display(
    type_name: str, prec: int
) -> None:
    datatype = to_fastcs(type_name, units="V")
    value = float(np.float32(1.2345678)) if type_name == "REAL" else 1.2345678901234567

    assert isinstance(datatype, ExactFloat)
    assert (datatype.units, datatype.prec) == ("V", prec)
    assert datatype.validate(value) == value
    assert Float(prec=2).validate(value) == 1.23, "FastCS's own Float rounds"
    shown = to_fastcs(type_name, precision=3)
    assert isinstance(shown, ExactFloat) and shown.prec == 3


def test_strings_and_arrays() -> None:
    assert to_fastcs("STRING(20)") == String(length=20)
    assert to_fastcs("STRING") == String(length=80)
    samples = to_fastcs("ARRAY [0..7] OF INT")
    bits = to_fastcs("ARRAY [1..4] OF BOOL")
    reals = to_fastcs("ARRAY [0..2] OF LREAL")

    assert isinstance(samples, Waveform) and samples.shape == (8,)
    assert np.dtype(samples.array_dtype) == np.int16
    assert isinstance(bits, Waveform) and np.dtype(bits.array_dtype) == np.uint8
    assert isinstance(reals, Waveform) and np.dtype(reals.array_dtype) == np.float64
    assert np.array_equal(samples.validate(np.arange(-4, 4)), np.arange(-4, 4))


@pytest.mark.parametrize(
    "type_name", ["ARRAY [0..1, 0..1] OF INT", "ARRAY [0..1] OF STRING(4)", "FOO"]
)
def test_unsupported_types_say_so(type_name: str) -> None:
    with pytest.raises(UnsupportedTypeError):
        to_fastcs(type_name)


def test_esi_enum_becomes_an_enum(el3104_types: dict[str, EsiDataType]) -> None:
    esi_type = el3104_types["DT0800EN03"]
    members = {item.value: item.text for item in esi_type.enum_items}
    assert esi_type.base_type is not None

    datatype = to_fastcs(
        esi_type.base_type, enum_members=members, enum_name="Presentation"
    )

    assert isinstance(datatype, Enum)
    assert datatype.names == [members[v] for v in sorted(members)]
    assert datatype.validate(1).name == members[1]
    with pytest.raises(ValueError):
        datatype.validate(max(members) + 1)
    with pytest.raises(UnsupportedTypeError):
        to_fastcs("REAL", enum_members=members)


def test_enum_labels_and_descriptions_fit_their_record_fields() -> None:
    members = {0: "x" * 30, 3: "x" * 30, 7: "", 9: "µ" * 20}

    labels = [member.name for member in enum_class("Long", members)]

    assert labels == ["x" * 25, "x" * 23 + " 3", "7", "µ" * 12]
    assert description("AI Standard Channel 1.Status.Limit 1 monitoring") == (
        "AI Standard Channel 1.Status.Limit 1 mon"
    )
    assert description("  a \n b ") == "a b"
    assert description(None) is None
    assert all(len(text.encode()) <= 40 for text in (description("°" * 30) or "", ""))


def test_engineering_units_are_a_float_with_egu_prec_and_range() -> None:
    volts = engineering("INT", Scaling(10 / 32767, 0.0, "V"))
    loop = engineering("INT", Scaling(16 / 32767, 4.0, "mA"))
    unit_only = engineering("DINT", Scaling(unit="N"))
    real = engineering("REAL", Scaling(2.0, 1.0, "bar", 3))

    assert volts == ExactFloat(units="V", prec=4, min=-32768 * 10 / 32767, max=10.0)
    assert volts.validate(32767 * (10 / 32767) + 0.0) == 10.0  # the top count fits
    assert isinstance(loop, ExactFloat)
    assert (loop.min, loop.max) == (pytest.approx(4 - 16 * 32768 / 32767), 20.0)
    assert unit_only == Int(units="N", min=-(2**31), max=2**31 - 1)
    assert real == ExactFloat(units="bar", prec=3)
    with pytest.raises(UnsupportedTypeError, match="no engineering units"):
        engineering("STRING(10)", Scaling(2.0))


def test_pv_lists_name_alarm_states_by_their_fastcs_type() -> None:
    assert type_label(AlarmBool(severities=(0, 2))) == "Bool"
    assert type_label(AlarmInt(set_severity=1)) == "Int"
    assert type_label(ExactFloat()) == "ExactFloat"


def test_coe_numbers_show_their_esi_unit() -> None:
    def coe(type_name: str, units: str) -> Any:
        return coe_datatype(CoePoint("x", 0x8000, 1, type_name, 16, False, units=units))

    assert coe("INT", "degC") == Int(units="degC", min=-32768, max=32767)
    assert coe("REAL", "mV/V").units == "mV/V"
    assert coe("STRING(8)", "s") == String(length=8)
    assert coe("UINT", "") == Int(min=0, max=65535)


def test_values_written_in_engineering_units_become_counts() -> None:
    def point(type_name: str, kind: PointKind = PointKind.SCALAR) -> Point:
        return Point("k", "s", "a", type_name, kind, 0xF020, 0, 2, length=3,
                     writable=True, scaling=Scaling(10 / 32767, 0.0, "V"))  # fmt: skip

    assert from_engineering(point("INT"), 2.5) == 8192  # 8191.75 -> nearest
    assert from_engineering(point("INT", PointKind.ARRAY), [0.0, 5.0, -10.0]) == [
        0,
        16384,
        -32767,
    ]
    assert from_engineering(point("REAL"), 1.0) == pytest.approx(3276.7)
    unscaled = Point("k", "s", "a", "INT", PointKind.SCALAR, 0xF020, 0, 2)
    assert from_engineering(unscaled, 7) == 7
    # what the setpoint then shows: the count written, in volts
    assert engineering_value(point("INT"), 8192) == pytest.approx(2.50008, abs=1e-5)
    shown = engineering_value(point("INT", PointKind.ARRAY), [0, 16384, -32767])
    assert shown.tolist() == pytest.approx([0.0, 5.00015, -10.0], abs=1e-5)
    assert engineering_value(unscaled, 7) == 7


def test_the_record_fastcs_makes_for_each_datatype() -> None:
    """What the autosave request names fields of; an enum of more members
    than an mbbi has states is a long string (a waveform), as FastCS does."""
    from fastcs.transports.epics.ca.util import MBB_MAX_CHOICES

    states = enum_class("States", {i: f"S{i}" for i in range(MBB_MAX_STATES)})
    more = enum_class("More", {i: f"S{i}" for i in range(MBB_MAX_STATES + 1)})

    assert MBB_MAX_STATES == MBB_MAX_CHOICES
    assert [ca_record_type(t) for t in (Bool(), Int(), Float(), Enum(states))] == [
        "bi", "longin", "ai", "mbbi"
    ]  # fmt: skip
    assert [
        ca_record_type(t, output=True) for t in (Bool(), Int(), Float(), Enum(states))
    ] == ["bo", "longout", "ao", "mbbo"]
    assert {
        ca_record_type(t, output=output)
        for t in (Enum(more), String(), Waveform(np.float64, (4,)))
        for output in (False, True)
    } == {"waveform"}
