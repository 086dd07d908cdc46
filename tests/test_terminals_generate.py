"""Generation from the real ESI files (and the EL3356-0010 fixture)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fastcs_ethercat.esi.catalog import EsiCatalog, parse_all
from fastcs_ethercat.terminals.checks import terminal_problems
from fastcs_ethercat.terminals.files import parse_terminal_text, terminal_file_text
from fastcs_ethercat.terminals.generate import esi_file_name, terminal_from_esi
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.selection import select_group
from fastcs_ethercat.terminals.symbols import expanded_symbols

from .test_terminals_support import real_catalog


@pytest.fixture(scope="module")
def catalog() -> EsiCatalog:
    return real_catalog()


@pytest.fixture(scope="module")
def generated(catalog: EsiCatalog) -> dict[str, TerminalType]:
    names = ["EK1100", "EL1014", "EL1502", "EL3104", "EL3356-0010", "EL3702"]
    names += ["EL4732", "ELM3704-0000", "EP4374-0002"]
    return {name: terminal_from_esi(catalog.load(name)) for name in names}


def _node(terminal: TerminalType, name: str) -> int:
    return next(
        i for i, n in enumerate(terminal.symbol_nodes) if n.name_template == name
    )


def test_every_generated_terminal_is_consistent(
    generated: dict[str, TerminalType],
) -> None:
    for terminal in generated.values():
        assert terminal_problems(terminal) == []


def test_el3104_standard_and_compact(generated: dict[str, TerminalType]) -> None:
    el3104 = generated["EL3104"]
    assert el3104.identity.product_code == 0x0C203052
    assert el3104.identity.revision_number == 0x00110000
    assert [(g.name, g.is_default) for g in el3104.pdo_groups] == [
        ("Standard", True),
        ("Compact", False),
    ]
    assert el3104.selected_pdo_group == "Standard"
    standard, compact = el3104.symbol_nodes
    assert standard.name_template == "AI Standard Channel {channel}"
    assert standard.type_name == "AI Standard Channel {channel}_TYPE"
    assert standard.channels == [1, 2, 3, 4]
    assert standard.pdo_indices == [0x1A00, 0x1A02, 0x1A04, 0x1A06]
    assert (standard.bit_size, standard.selected, standard.access) == (32, True, "ro")
    bits = {m.name: (m.bit_offset, m.bit_size, m.type_name) for m in standard.members}
    assert bits["Status__Underrange"] == (0, 1, "BIT")
    assert bits["Status__Limit 1"] == (2, 2, "BIT2")
    assert bits["Status__TxPDO Toggle"] == (15, 1, "BIT")
    assert bits["Value"] == (16, 16, "INT")
    value = standard.members[-1]
    assert value.coe == ["0x6000:11", "0x6010:11", "0x6020:11", "0x6030:11"]
    assert value.dscale == "+/-10"
    assert (compact.type_name, compact.bit_size, compact.selected) == ("INT", 16, False)
    assert el3104.pdo_groups[0].symbol_indices == [0]
    assert el3104.pdo_groups[1].symbol_indices == [1]
    assert el3104.esi_file == "Beckhoff EL31xx.xml"
    assert not any(o.selected for o in el3104.coe_objects)
    settings = next(o for o in el3104.coe_objects if o.index == 0x8000)
    presentation = next(s for s in settings.sub_items if s.name == "Presentation")
    assert [e.text for e in presentation.enum][:2] == ["Signed", "Unsigned"]
    assert all(not 0x1400 <= o.index < 0x1D00 for o in el3104.coe_objects)


def test_static_terminals_start_all_selected(
    generated: dict[str, TerminalType],
) -> None:
    el1014 = generated["EL1014"]
    assert el1014.pdo_groups == [] and el1014.selected_pdo_group is None
    (channel,) = el1014.symbol_nodes
    assert (channel.name_template, channel.type_name, channel.bit_size) == (
        "Channel {channel}",
        "BIT",
        1,
    )
    assert channel.selected and [m.name for m in channel.members] == ["Input"]
    assert generated["EK1100"].symbol_nodes == []


def test_el1502_counter_groups(generated: dict[str, TerminalType]) -> None:
    el1502 = generated["EL1502"]
    default = el1502.active_group
    assert default is not None and default.is_default
    combined = _node(el1502, "CNT Inputs")
    per_channel = _node(el1502, "CNT Inputs Channel {channel}")
    assert combined in default.symbol_indices
    assert el1502.symbol_nodes[combined].selected
    assert not el1502.symbol_nodes[per_channel].selected
    outputs = el1502.symbol_nodes[_node(el1502, "CNT Outputs")]
    assert (outputs.direction, outputs.access) == ("output", "rw")


def test_el3702_oversampling(generated: dict[str, TerminalType]) -> None:
    el3702 = generated["EL3702"]
    over = el3702.oversampling
    assert over is not None and not over.by_group
    assert (over.default_factor, over.selected_factor) == (10, 10)
    assert 100 in over.factors and over.pdo_indices == [0x1A00, 0x1A80]
    sample = el3702.symbol_nodes[_node(el3702, "Ch{channel} Sample 0")]
    assert sample.oversampled and sample.type_name == "Ch{channel} Sample 0_TYPE_ARR"
    assert [m.name for m in sample.members] == ["Ch{channel} Value"]
    symbols = {s.name: s for s in expanded_symbols(el3702)}
    assert symbols["Ch2 Sample 0"].bit_size == 160
    assert symbols["Ch2 Sample 0"].members[0].name == "Ch2 Value"
    assert symbols["Ch1 CycleCount"].type_name == "UINT"


def test_el4732_oversampled_outputs(generated: dict[str, TerminalType]) -> None:
    el4732 = generated["EL4732"]
    sample = el4732.symbol_nodes[_node(el4732, "Ch{channel} Sample 0")]
    assert sample.oversampled and sample.direction == "output"
    assert el4732.oversampling is not None


def test_elm3704_factor_follows_the_group(generated: dict[str, TerminalType]) -> None:
    elm = generated["ELM3704-0000"]
    over = elm.oversampling
    assert over is not None and over.by_group
    assert over.factors[0] == 1 and over.factors[-1] == 100
    default = elm.active_group
    assert default is not None and default.oversampling_factor == over.selected_factor
    ten = next(g for g in elm.pdo_groups if g.name == "Oversampling 10 (24Bit)")
    assert ten.oversampling_factor == 10
    samples = [elm.symbol_nodes[i] for i in ten.symbol_indices]
    assert any(n.name_template == "PAI Samples 10 Channel {channel}" for n in samples)
    # a node never spans channels that sit in different groups
    for node in elm.symbol_nodes:
        memberships = {
            frozenset(g.name for g in elm.pdo_groups if index in g.pdo_indices)
            for index in node.pdo_indices
        }
        assert len(memberships) == 1, node.name_template


def test_ep4374_channels_need_not_start_at_one(
    generated: dict[str, TerminalType],
) -> None:
    ep = generated["EP4374-0002"]
    outputs = [n for n in ep.symbol_nodes if n.direction == "output"]
    assert [n.channels for n in outputs] == [[3, 4]]
    assert all(n.selected for n in outputs)


def test_el3356_fixture(generated: dict[str, TerminalType]) -> None:
    el3356 = generated["EL3356-0010"]
    assert el3356.identity.revision_number == 0x0011000A
    assert el3356.esi_file == "EL3356-0010-fixture.xml"
    names = [n.name_template for n in el3356.symbol_nodes]
    assert "RMB Value (INT32)" in names and "RMB Value (Real)" in names
    real = el3356.symbol_nodes[names.index("RMB Value (Real)")]
    assert (real.type_name, real.selected) == ("REAL", False)
    # The CoE objects as catio-terminals' data (from Beckhoff's ESI) has them.
    settings = {o.index: o for o in el3356.coe_objects}[0x8000]
    assert (settings.name, settings.bit_size) == ("RMB Settings", 448)
    averager = {s.subindex: s for s in settings.sub_items}[0x03]
    assert (averager.name, averager.type_name, averager.default_data) == (
        "Mode0 enable averager",
        "BOOL",
        "01",
    )
    assert {0x8010, 0x801E, 0x801F, 0x8020, 0x802E, 0x802F} <= {
        o.index for o in el3356.coe_objects
    }


def test_esi_file_names_drop_directories_and_zips() -> None:
    assert esi_file_name("/x/Beckhoff EL31xx.xml") == "Beckhoff EL31xx.xml"
    assert esi_file_name("/c/Beckhoff_EtherCAT_XML.zip!Beckhoff EL31xx.xml") == (
        "Beckhoff EL31xx.xml"
    )


@pytest.mark.parametrize(
    "file_name", ["Beckhoff EL1xxx.xml", "Beckhoff EL15xx.xml", "Beckhoff EP4xxx.xml"]
)
def test_every_device_of_a_file_generates_a_stable_file(
    file_name: str, shared_esi: Path
) -> None:
    """All revisions of all devices, with same-named PDOs (EL1262) and gaps."""
    devices = parse_all([shared_esi / file_name]).devices
    assert devices
    for device in devices:
        terminal = terminal_from_esi(device)
        text = terminal_file_text({device.type_name: terminal})
        assert terminal_file_text(parse_terminal_text(text, "x.yaml")) == text
        for group in terminal.pdo_groups:
            assert terminal_problems(select_group(terminal, group.name)) == []
