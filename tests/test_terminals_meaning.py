"""What values mean: DScale scalings, severities from names, CoE units, DESC.

The scalings are Beckhoff's (full scale at the signed type's largest count,
the range's low end at 0); every DScale the real ESI files carry has one.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from lxml import etree

from fastcs_ethercat.terminals.files import read_terminal_file
from fastcs_ethercat.terminals.meaning import (
    MAX_DESCRIPTION,
    Scaling,
    coe_unit,
    describe,
    dscale_scaling,
    member_scaling,
    member_severity,
    precision_of,
    severity_of_name,
)
from fastcs_ethercat.terminals.model import SymbolMember
from tests.conftest import TERMINALS_DIR


@pytest.mark.parametrize(
    ("dscale", "type_name", "scale", "offset", "unit", "decimals"),
    [
        ("+/-10", "INT", 10 / 32767, 0.0, "V", 4),  # EL3104: 0x7FFF = +10 V
        ("+/-5", "INT", 5 / 32767, 0.0, "V", 4),
        ("0-10", "INT", 10 / 32767, 0.0, "V", 4),
        ("0-20", "INT", 20 / 32767, 0.0, "mA", 4),
        ("4-20", "INT", 16 / 32767, 4.0, "mA", 4),  # 0 = 4 mA, 0x7FFF = 20 mA
        ("+/-10", "DINT", 10 / (2**31 - 1), 0.0, "V", 6),  # EL3602: 0x7FFFFFFF
        ("+/-75mV", "DINT", 75 / (2**31 - 1), 0.0, "mV", 6),  # EL3602-0010
        ("0-20", "DINT", 20 / (2**31 - 1), 0.0, "mA", 6),  # EL3612
        ("0.1°", "INT", 0.1, 0.0, "degC", 1),  # EL3202: 1/10 °C per count
        ("0.01°", "INT", 0.01, 0.0, "degC", 2),
    ],
)
def test_dscale_gives_beckhoffs_scaling(
    dscale: str, type_name: str, scale: float, offset: float, unit: str, decimals: int
) -> None:
    scaling = dscale_scaling(dscale, type_name)

    assert scaling is not None
    assert scaling.scale == pytest.approx(scale, rel=1e-12)
    assert (scaling.offset, scaling.unit, scaling.decimals) == (offset, unit, decimals)
    assert scaling.converts


@pytest.mark.parametrize(
    ("dscale", "type_name"),
    [("+/-10", "UDINT"), ("+/-10", "REAL"), ("fast", "INT"), ("10-", "INT")],
)
def test_dscale_without_a_known_meaning_gives_none(dscale: str, type_name: str) -> None:
    assert dscale_scaling(dscale, type_name) is None


def test_every_dscale_of_the_real_esi_files_has_a_meaning(shared_esi: Path) -> None:
    found: set[tuple[str, str]] = set()
    for path in sorted(shared_esi.rglob("*.xml")):
        for element in etree.parse(str(path)).iter("DataType"):
            if element.get("DScale") is not None:
                found.add((element.get("DScale") or "", (element.text or "").strip()))

    assert len(found) >= 10
    assert [pair for pair in sorted(found) if dscale_scaling(*pair) is None] == []


def test_precision_shows_one_count() -> None:
    assert [precision_of(s) for s in (1.0, 0.1, 0.01, 10 / 32767, 1e-9)] == [
        0,
        1,
        2,
        4,
        6,
    ]
    assert Scaling(0.5, precision=3).decimals == 3


def _member(**fields: object) -> SymbolMember:
    base: dict[str, object] = {"name": "Value", "fastcs_name": "value",
                               "type_name": "INT", "bit_offset": 16, "bit_size": 16,
                               "coe": []}  # fmt: skip
    return SymbolMember.model_validate({**base, **fields})


def test_overrides_go_on_top_of_the_dscale() -> None:
    plain = member_scaling(_member(dscale="+/-10"))
    in_millivolts = member_scaling(_member(dscale="+/-10", unit="mV", scale=0.30518))
    offset_only = member_scaling(_member(dscale="4-20", offset=0.0))
    unit_only = member_scaling(_member(type_name="REAL", unit="N"))

    assert plain is not None and plain.unit == "V"
    assert in_millivolts == Scaling(0.30518, 0.0, "mV", None)
    assert in_millivolts is not None and in_millivolts.decimals == 1
    assert offset_only is not None and offset_only.offset == 0.0
    assert offset_only.scale == pytest.approx(16 / 32767)
    assert unit_only == Scaling(1.0, 0.0, "N", None)
    assert unit_only is not None and not unit_only.converts  # no raw twin
    assert member_scaling(_member()) is None
    assert member_scaling(_member(type_name="BIT", bit_size=1, dscale="+/-10")) is None


def test_overrides_are_checked() -> None:
    with pytest.raises(ValueError, match="scale of 0"):
        _member(scale=0)
    with pytest.raises(ValueError, match="finite"):
        _member(offset=float("inf"))
    with pytest.raises(ValueError, match="EGU"):
        _member(unit="µ" * 8)  # 16 bytes in UTF-8


@pytest.mark.parametrize(
    ("name", "severity"),
    [
        ("Status__Error", "major"),
        ("Status__Sync error", "major"),
        ("Status__TxPDO State", "major"),
        ("Status__Data invalid", "major"),
        ("WcState.WcState", "major"),
        ("Inputs.Frm0WcState", "major"),
        ("Status__Underrange", "minor"),
        ("Overrange", "minor"),
        ("Status__Limit 1", "minor"),
        ("Limit 2", "minor"),
        ("Status__TxPDO Toggle", "none"),
        ("Status__Counter inhibited", "none"),
        ("WcState.InputToggle", "none"),
        ("Input", "none"),
    ],
)
def test_severity_from_the_esi_name(name: str, severity: str) -> None:
    assert severity_of_name(name) == severity


def test_outputs_and_values_carry_no_severity_unless_set() -> None:
    error = _member(name="Status__Error", type_name="BIT", bit_size=1)

    assert member_severity(error, "input") == "major"
    assert member_severity(error, "output") == "none"
    assert member_severity(_member(name="Error"), "input") == "none"  # 16 bits
    assert member_severity(error.model_copy(update={"severity": "minor"}), "input") == (
        "minor"
    )


def test_shipped_terminals_status_bits() -> None:
    """Every Error bit of the shipped types is MAJOR, every range bit MINOR."""
    severities: dict[str, set[str]] = {}
    for path in TERMINALS_DIR.glob("*.yaml"):
        for terminal in read_terminal_file(path).values():
            for node in terminal.symbol_nodes:
                for member in node.members:
                    last = member.name.split("__")[-1]
                    severity = member_severity(member, node.direction)
                    severities.setdefault(last, set()).add(severity)

    assert severities["Error"] == {"major"}
    assert severities["Overrange"] == severities["Underrange"] == {"minor"}
    assert severities["Limit 1"] == {"minor"}
    assert severities["TxPDO Toggle"] == {"none"}


@pytest.mark.parametrize(
    ("code", "text"),
    [
        ("#x002d0000", "degC"),
        ("#xfd040000", "mA"),
        ("#xfd262600", "mV/V"),
        ("#xf7030000", "ns"),
        ("#xfc030000", "100us"),  # 10^-4 s: a count is 100 µs
        ("#xfe260000", "10mV"),
        ("#x00280000", "Ohm"),
        ("#x00200000", "Hz"),
        ("#x00470000", ""),  # not in CiA 303-2's SI tables
        ("", ""),
        ("bogus", ""),
    ],
)
def test_coe_unit_codes(code: str, text: str) -> None:
    assert coe_unit(code) == text


def test_descriptions_come_from_esi_names_and_fit() -> None:
    assert describe("EL3104", "AI Standard Channel 1", "Status__Underrange") == (
        "EL3104 AI Standard Ch1 Underrange"
    )
    assert describe("EL3104", "AI Compact Channel 2", "Value") == (
        "EL3104 AI Compact Ch2 Value"
    )
    assert describe("EL3104", "WcState.WcState") == "EL3104 WcState"
    assert describe(None, "Inputs", "Frm0WcState") == "Inputs Frm0WcState"
    long = describe("ELM3704-0000", "PAI Synchronous Oversampling Channel 1", "Value")
    assert long == "PAI Synchronous Oversampling Ch1 Value"  # no room for the type
    assert len(describe("X", "word " * 20)) <= MAX_DESCRIPTION
