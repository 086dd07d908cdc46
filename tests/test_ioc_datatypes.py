"""TwinCAT / ESI types -> FastCS datatypes: width, sign, range, precision."""

from __future__ import annotations

import numpy as np
import pytest
from fastcs.datatypes import Bool, Enum, Float, Int, String, Waveform
from lxml import etree

from fastcs_ethercat.esi.dictionary import parse_data_type
from fastcs_ethercat.esi.model import EsiDataType
from fastcs_ethercat.ioc.datatypes import (
    EXACT_DOUBLE_INTEGER,
    BitField,
    ExactFloat,
    IntegralFloat,
    UnsupportedTypeError,
    description,
    enum_class,
    to_fastcs,
)
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
    np.testing.assert_array_equal(samples.validate(np.arange(-4, 4)), np.arange(-4, 4))


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


def test_status_word_bits_become_one_bool_each(
    el3104_types: dict[str, EsiDataType],
) -> None:
    status = [
        item
        for item in el3104_types["DT6000"].sub_items
        if 16 <= item.bit_offset < 32  # the Status word of the TxPDO
    ]
    fields = [BitField(i.name, i.bit_offset - 16, i.bit_size) for i in status]
    word = (1 << 1) | (3 << 2) | (1 << 6) | (1 << 14) | (1 << 15)

    values = {f.name: f.extract(word) for f in fields}
    datatypes = {f.name: f.datatype() for f in fields}

    assert values == {
        "Underrange": False,
        "Overrange": True,
        "Limit 1": 3,
        "Limit 2": 0,
        "Error": True,
        "Sync error": False,
        "TxPDO State": True,
        "TxPDO Toggle": True,
    }
    assert datatypes["Overrange"] == Bool()
    assert datatypes["Limit 1"] == Int(min=0, max=3)
    limit = BitField("Limit 1", 2, 2).datatype({0: "off", 1: "above", 2: "below"})
    assert isinstance(limit, Enum)
