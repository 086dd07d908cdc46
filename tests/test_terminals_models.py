"""Terminal models: validation, consistency rules, names, expanded symbols."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from fastcs_ethercat.terminals.checks import check_terminal, terminal_problems
from fastcs_ethercat.terminals.files import parse_terminal_text, terminal_file_text
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.model import (
    CoeEnumItem,
    CoeObject,
    CoeSubItem,
    Identity,
    Oversampling,
    PdoGroup,
    SymbolMember,
    SymbolNode,
    TerminalType,
    parse_coe_address,
)
from fastcs_ethercat.terminals.names import snake_name, templatize
from fastcs_ethercat.terminals.selection import UnknownGroupError, select_group
from fastcs_ethercat.terminals.symbols import expanded_symbols
from tests.conftest import TERMINALS_DIR


def _member(
    name: str, offset: int, size: int, type_name: str, *coe: str
) -> SymbolMember:
    return SymbolMember(
        name=name,
        fastcs_name=snake_name(name),
        type_name=type_name,
        bit_offset=offset,
        bit_size=size,
        coe=list(coe),
    )


def _el3104_like() -> TerminalType:
    """A two-channel Standard/Compact analog input, as the generator writes one."""
    standard = SymbolNode(
        name_template="AI Standard Channel {channel}",
        fastcs_name="ai_standard_channel_{channel}",
        selected=True,
        channels=[1, 2],
        pdo_indices=[0x1A00, 0x1A02],
        direction="input",
        access="ro",
        type_name="AI Standard Channel {channel}_TYPE",
        bit_size=32,
        members=[
            _member("Status__Underrange", 0, 1, "BIT", "0x6000:01", "0x6010:01"),
            _member("Status__Limit 1", 2, 2, "BIT2", "0x6000:03", "0x6010:03"),
            _member("Value", 16, 16, "INT", "0x6000:11", "0x6010:11"),
        ],
    )
    compact = SymbolNode(
        name_template="AI Compact Channel {channel}",
        fastcs_name="ai_compact_channel_{channel}",
        selected=False,
        channels=[1, 2],
        pdo_indices=[0x1A01, 0x1A03],
        direction="input",
        access="ro",
        type_name="INT",
        bit_size=16,
        members=[_member("Value", 0, 16, "INT", "0x6000:11", "0x6010:11")],
    )
    return TerminalType(
        identity=Identity(
            vendor_id=2, product_code=0x0C203052, revision_number=0x110000
        ),
        description="EL3104 4Ch. Ana. Input +/-10V Diff.",
        group_type="AnaIn",
        pdo_groups=[
            PdoGroup(
                name="Standard",
                is_default=True,
                pdo_indices=[0x1A00, 0x1A02],
                symbol_indices=[0],
            ),
            PdoGroup(
                name="Compact",
                is_default=False,
                pdo_indices=[0x1A01, 0x1A03],
                symbol_indices=[1],
            ),
        ],
        selected_pdo_group="Standard",
        symbol_nodes=[standard, compact],
        coe_objects=[
            CoeObject(
                index=0x8000,
                name="AI Settings",
                fastcs_name="ai_settings_8000",
                selected=True,
                type_name="DT8000",
                bit_size=160,
                access="rw",
                sub_items=[
                    CoeSubItem(
                        subindex=2,
                        name="Presentation",
                        fastcs_name="presentation",
                        type_name="DT0800EN03",
                        bit_size=3,
                        bit_offset=17,
                        access="rw",
                        default_data="00",
                        enum=[CoeEnumItem(value=0, text="Signed")],
                    )
                ],
            )
        ],
    )


def test_a_consistent_terminal_has_no_problems() -> None:
    assert terminal_problems(_el3104_like()) == []


def test_hex_fields_are_written_in_hex_and_read_back_as_ints() -> None:
    text = terminal_file_text({"EL3104": _el3104_like()})
    assert "product_code: 0x0c203052" in text
    assert "revision_number: 0x00110000" in text
    assert "pdo_indices: [0x1a00, 0x1a02]" in text
    assert "- index: 0x8000" in text
    assert "- subindex: 0x02" in text
    assert "- {value: 0, text: Signed}" in text
    back = parse_terminal_text(text, "EL3104.yaml")["EL3104"]
    assert back.identity.product_code == 0x0C203052
    assert back.symbol_nodes[0].pdo_indices == [0x1A00, 0x1A02]
    assert back == _el3104_like()


def test_unknown_keys_are_rejected() -> None:
    data = _el3104_like().model_dump()
    data["symbol_nodes"][0]["selectd"] = True
    with pytest.raises(ValidationError, match="selectd"):
        TerminalType.model_validate(data)


def test_fastcs_names_must_be_snake_case() -> None:
    with pytest.raises(ValidationError, match="fastcs_name"):
        SymbolMember(
            name="Value",
            fastcs_name="Value",
            type_name="INT",
            bit_offset=0,
            bit_size=16,
            coe=[],
        )


def test_coe_addresses_are_index_colon_subindex() -> None:
    assert parse_coe_address("0x6000:11") == (0x6000, 0x11)
    with pytest.raises(ValidationError):
        SymbolMember(
            name="Value",
            fastcs_name="value",
            type_name="INT",
            bit_offset=0,
            bit_size=16,
            coe=["6000:11"],
        )


def _problem_texts(terminal: TerminalType) -> list[str]:
    return [
        ".".join(map(str, p.loc)) + ": " + p.message
        for p in terminal_problems(terminal)
    ]


def test_a_selected_symbol_outside_the_selected_group_is_a_problem() -> None:
    terminal = _el3104_like()
    terminal.symbol_nodes[1].selected = True
    problems = _problem_texts(terminal)
    assert problems == [
        "symbol_nodes.1.selected: selected, but it belongs only to PDO group(s) "
        "['Compact'], not to the selected group 'Standard'"
    ]


def test_channel_and_pdo_index_counts_must_agree() -> None:
    terminal = _el3104_like()
    terminal.symbol_nodes[0].pdo_indices = [0x1A00]
    terminal.symbol_nodes[1].channels = []
    problems = _problem_texts(terminal)
    assert any(p.startswith("symbol_nodes.0.pdo_indices: want 2") for p in problems)
    assert any(p.startswith("symbol_nodes.1.channels:") for p in problems)


def test_group_rules() -> None:
    terminal = _el3104_like()
    terminal.selected_pdo_group = "Legacy"
    terminal.pdo_groups[1].is_default = True
    terminal.pdo_groups[1].symbol_indices = [7]
    problems = _problem_texts(terminal)
    assert any("symbol index 7 is out of range" in p for p in problems)
    assert any("want one default group" in p for p in problems)
    assert any("no PDO group named 'Legacy'" in p for p in problems)


def test_members_must_not_overlap_or_leave_the_symbol() -> None:
    terminal = _el3104_like()
    members = terminal.symbol_nodes[0].members
    members[1].bit_offset = 0
    members[2].bit_size = 32
    problems = _problem_texts(terminal)
    assert any("members.1.bit_offset: overlaps" in p for p in problems)
    assert any("members.2.bit_size: ends at bit 48" in p for p in problems)


def test_duplicate_fastcs_names_and_coe_indices_are_problems() -> None:
    terminal = _el3104_like()
    terminal.symbol_nodes[1].fastcs_name = "ai_standard_channel_{channel}"
    terminal.coe_objects.append(terminal.coe_objects[0].model_copy())
    problems = _problem_texts(terminal)
    assert any("is also used by symbol_nodes[0]" in p for p in problems)
    assert any("duplicate CoE index 0x8000" in p for p in problems)
    with pytest.raises(ValueError, match=r"^EL3104\.symbol_nodes\.1\.fastcs_name"):
        check_terminal("EL3104", terminal)


def test_oversampling_factors_must_be_offered() -> None:
    terminal = _el3104_like()
    terminal.oversampling = Oversampling(
        factors=[1, 2, 4], default_factor=2, selected_factor=3, pdo_indices=[0x1A00]
    )
    assert _problem_texts(terminal) == [
        "oversampling.selected_factor: 3 is not one of the factors [1, 2, 4]"
    ]


def test_select_group_flips_the_flags() -> None:
    compact = select_group(_el3104_like(), "Compact")
    assert compact.selected_pdo_group == "Compact"
    assert [n.selected for n in compact.symbol_nodes] == [False, True]
    assert terminal_problems(compact) == []
    back = select_group(compact, "Standard")
    assert [n.selected for n in back.symbol_nodes] == [True, False]
    with pytest.raises(UnknownGroupError, match="'Standard', 'Compact'"):
        select_group(compact, "Legacy")


def test_expanded_symbols_fill_in_channels() -> None:
    symbols = expanded_symbols(_el3104_like())
    assert [s.name for s in symbols] == [
        "AI Standard Channel 1",
        "AI Standard Channel 2",
        "AI Compact Channel 1",
        "AI Compact Channel 2",
    ]
    second = symbols[1]
    assert second.type_name == "AI Standard Channel 2_TYPE"
    assert second.fastcs_name == "ai_standard_channel_2"
    assert second.pdo_index == 0x1A02
    assert second.byte_size == 4
    value = second.members[-1]
    assert (value.coe_index, value.coe_subindex, value.bit_offset) == (0x6010, 0x11, 16)
    assert second.members[0].path == ("Status", "Underrange")
    selected = expanded_symbols(_el3104_like(), selected_only=True)
    assert [s.name for s in selected] == [
        "AI Standard Channel 1",
        "AI Standard Channel 2",
    ]


def test_expanded_symbols_of_chosen_nodes_in_their_order() -> None:
    """Expanding only some nodes gives those nodes' symbols of the whole
    expansion, node by node in the order asked (what a terminal serves)."""
    for registered in load_terminals([TERMINALS_DIR]):
        terminal = registered.terminal
        everything = expanded_symbols(terminal)
        for group in [None, *(g.name for g in terminal.pdo_groups)]:
            nodes = terminal.served_nodes(group)
            rank = {node: k for k, node in enumerate(nodes)}
            wanted = sorted(
                (s for s in everything if s.node_index in rank),
                key=lambda s: rank[s.node_index],
            )
            assert expanded_symbols(terminal, nodes=nodes) == wanted
            assert expanded_symbols(terminal, nodes=nodes[::-1]) == sorted(
                wanted, key=lambda s: -rank[s.node_index]
            )


def test_oversampled_symbols_are_factor_times_larger() -> None:
    terminal = _el3104_like()
    node = terminal.symbol_nodes[1]
    node.oversampled = True
    terminal.oversampling = Oversampling(
        factors=[1, 10], default_factor=10, selected_factor=10, pdo_indices=[0x1A01]
    )
    compact = expanded_symbols(terminal)[2]
    assert (compact.samples, compact.sample_bit_size, compact.bit_size) == (10, 16, 160)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("AI Standard Channel {channel}", "ai_standard_channel_{channel}"),
        ("Ch{channel} CycleCount", "ch{channel}_cyclecount"),
        ("Status__TxPDO Toggle", "status_txpdo_toggle"),
        ("RMB Value (INT32)", "rmb_value_int32"),
        ("Samples__ARRAY [0]", "samples_array_0"),
        ("1st value", "n1st_value"),
    ],
)
def test_snake_names(text: str, expected: str) -> None:
    assert snake_name(text) == expected


def test_templatize_only_replaces_the_whole_channel_number() -> None:
    assert templatize("Ch2 Value", 2) == "Ch{channel} Value"
    assert templatize("Status 12", 2) == "Status 12"
