"""`terminals select` / `coe`: the choices the editor makes, from the command line."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.terminals.files import read_terminal_file, terminal_file_text
from fastcs_ethercat.terminals.selection import (
    SelectionError,
    parse_coe_target,
    rename_symbol,
    select_coe,
    select_symbols,
    set_oversampling,
)

from .test_terminals_support import (
    TERMINALS,
    needs_esi,
    regenerated_old_el3104,
    run_cli,
)


@pytest.fixture
def el3104(tmp_path: Path) -> Path:
    path = tmp_path / "EL3104.yaml"
    shutil.copy(TERMINALS / "EL3104.yaml", path)
    return path


def test_select_and_deselect_symbols_by_template_or_fastcs_name(el3104: Path) -> None:
    off = run_cli("terminals", "select", str(el3104), "--off",
                  "ai_standard_channel_{channel}")  # fmt: skip
    assert off.code == 0, off.err
    assert off.out == "EL3104: 0 of 2 symbols selected\n"
    terminal = read_terminal_file(el3104)["EL3104"]
    assert [n.selected for n in terminal.symbol_nodes] == [False, False]
    on = run_cli("terminals", "select", str(el3104), "ai standard channel {channel}")
    assert on.code == 0, on.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_a_symbol_of_another_group_or_a_channel_name_is_refused(el3104: Path) -> None:
    other = run_cli("terminals", "select", str(el3104), "AI Compact Channel {channel}")
    assert other.code == 2 and other.err.count("\n") == 1
    assert "belongs to PDO group 'Compact', not to the selected 'Standard'" in (
        other.err
    )
    channel = run_cli("terminals", "select", str(el3104), "AI Standard Channel 2")
    assert channel.code == 2
    assert "is one channel of 'AI Standard Channel {channel}'" in channel.err
    unknown = run_cli("terminals", "select", str(el3104), "Nothing")
    assert unknown.code == 2 and "no symbol 'Nothing' (symbols: " in unknown.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_coe_objects_and_sub_indices(el3104: Path) -> None:
    whole = run_cli("terminals", "coe", str(el3104), "0x8000", "8010")
    assert whole.code == 0, whole.err
    terminal = read_terminal_file(el3104)["EL3104"]
    on = {o.index for o in terminal.coe_objects if o.selected}
    assert on == {0x8000, 0x8010}
    one = run_cli("terminals", "coe", str(el3104), "0x8020:0x11")
    assert one.code == 0, one.err
    obj = next(o for o in read_terminal_file(el3104)["EL3104"].coe_objects
               if o.index == 0x8020)  # fmt: skip
    assert obj.selected
    assert [s.subindex for s in obj.sub_items if s.selected] == [0x11]
    assert "      selected: false\n" in el3104.read_text(encoding="utf-8")
    off = run_cli("terminals", "coe", str(el3104), "--off", "0x8020:11", "0x8000",
                  "0x8010")  # fmt: skip
    assert off.code == 0, off.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()
    bad = run_cli("terminals", "coe", str(el3104), "0x8000:99")
    assert bad.code == 2 and "has no sub-index 99" in bad.err
    typo = run_cli("terminals", "coe", str(el3104), "0x80g0")
    assert typo.code == 2 and "'0x80g0' is not a CoE address" in typo.err


def test_choices_in_code_match_the_cli(el3104: Path) -> None:
    terminal = read_terminal_file(el3104)["EL3104"]
    changed = select_coe(select_symbols(terminal, ["AI Standard Channel {channel}"],
                                        on=False), ["0x8000"])  # fmt: skip
    assert run_cli("terminals", "select", str(el3104), "--off",
                   "AI Standard Channel {channel}").code == 0  # fmt: skip
    assert run_cli("terminals", "coe", str(el3104), "0x8000").code == 0
    assert el3104.read_text(encoding="utf-8") == terminal_file_text({"EL3104": changed})
    assert parse_coe_target("#x8000:1A") == (0x8000, 0x1A)


def test_names_and_factor_are_validated() -> None:
    el3104 = read_terminal_file(TERMINALS / "EL3104.yaml")["EL3104"]
    with pytest.raises(SelectionError, match="needs \\{channel\\}"):
        rename_symbol(el3104, 0, "value")
    with pytest.raises(SelectionError, match="is not a fastcs_name"):
        rename_symbol(el3104, 0, "Value {channel}")
    with pytest.raises(SelectionError, match="already the name of another symbol"):
        rename_symbol(el3104, 0, "ai_compact_channel_{channel}")
    assert rename_symbol(el3104, 0, "ai{channel}").symbol_nodes[0].fastcs_name == (
        "ai{channel}"
    )
    with pytest.raises(SelectionError, match="does not oversample"):
        set_oversampling(el3104, 2)
    el3702 = read_terminal_file(TERMINALS / "EL3702.yaml")["EL3702"]
    assert el3702.oversampling is not None
    changed = set_oversampling(el3702, 20).oversampling
    assert changed is not None and changed.selected_factor == 20
    with pytest.raises(SelectionError, match="7 is not an offered factor"):
        set_oversampling(el3702, 7)


@needs_esi
def test_a_sub_index_choice_survives_regenerate(tmp_path: Path) -> None:
    def select_one_sub_index(path: Path) -> None:
        assert run_cli("terminals", "coe", str(path), "0x8020:11").code == 0

    path, result = regenerated_old_el3104(
        tmp_path / "terminals", tmp_path / "cache", select_one_sub_index
    )
    assert result.code == 0, result.err
    terminal = read_terminal_file(path)["EL3104"]
    assert terminal.identity.revision_number == 0x00110000
    obj = next(o for o in terminal.coe_objects if o.index == 0x8020)
    assert obj.selected and [s.subindex for s in obj.sub_items if s.selected] == [0x11]
