"""Regenerate keeps the engineer's choices and reports what changed."""

from __future__ import annotations

from pathlib import Path

import pytest

from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.terminals.files import read_terminal_file, write_terminal_file
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.merge import merge_terminal
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.selection import select_group

from .test_terminals_support import ESI_ARGS, cache_home, real_catalog, run_cli

OLD_EL3104 = 0x00100000


@pytest.fixture(scope="module")
def catalog() -> EsiCatalog:
    return real_catalog()


@pytest.fixture(scope="module")
def el3104_old(catalog: EsiCatalog) -> TerminalType:
    """EL3104 generated from its older revision, with choices made on it."""
    terminal = select_group(
        terminal_from_esi(catalog.load("EL3104", OLD_EL3104)), "Compact"
    )
    terminal.symbol_nodes[1].fastcs_name = "compact_{channel}"
    terminal.coe_objects[_coe(terminal, 0x8010)].selected = True
    return terminal


def _coe(terminal: TerminalType, index: int) -> int:
    return next(i for i, o in enumerate(terminal.coe_objects) if o.index == index)


def test_regenerate_keeps_choices_and_reports_the_revision(
    catalog: EsiCatalog, el3104_old: TerminalType
) -> None:
    fresh = terminal_from_esi(catalog.load("EL3104"))
    merged, report = merge_terminal("EL3104", el3104_old, fresh)
    assert merged.identity.revision_number == 0x00110000
    assert report.identity == ["revision_number 0x00100000 -> 0x00110000"]
    assert merged.selected_pdo_group == "Compact"
    assert [n.selected for n in merged.symbol_nodes] == [False, True]
    assert merged.symbol_nodes[1].fastcs_name == "compact_{channel}"
    assert merged.coe_objects[_coe(merged, 0x8010)].selected
    assert not merged.coe_objects[_coe(merged, 0x8000)].selected
    assert report.choices == []
    assert report.summary().startswith("EL3104: 1 identity change")


def test_regenerate_reports_added_removed_and_changed(
    catalog: EsiCatalog, el3104_old: TerminalType
) -> None:
    old = el3104_old.model_copy(deep=True)
    old.symbol_nodes[1].name_template = "AI Compact Old {channel}"
    old.symbol_nodes[0].bit_size = 48
    old.coe_objects = [o for o in old.coe_objects if o.index != 0x800F]
    old.coe_objects[_coe(old, 0x8000)].name = "AI Settings (old)"
    old.pdo_groups[1].name = "Legacy"
    old.selected_pdo_group = "Legacy"
    fresh = terminal_from_esi(catalog.load("EL3104"))
    merged, report = merge_terminal("EL3104", old, fresh)
    assert report.symbols_added == ["AI Compact Channel {channel} [channels 1,2,3,4]"]
    assert report.symbols_removed == ["AI Compact Old {channel} [channels 1,2,3,4]"]
    assert report.symbols_changed == [
        "AI Standard Channel {channel} [channels 1,2,3,4] (bit_size)"
    ]
    assert report.coe_added == ["0x800f AI Vendor data"]
    assert report.coe_changed == ["0x8000 AI Settings (name)"]
    assert report.groups_added == ["Compact"] and report.groups_removed == ["Legacy"]
    assert report.choices == [
        "selected_pdo_group 'Legacy' no longer exists; now 'Standard'"
    ]
    assert merged.selected_pdo_group == "Standard"
    assert [n.selected for n in merged.symbol_nodes] == [True, False]
    assert "symbol added: AI Compact Channel {channel} [channels 1,2,3,4]" in (
        report.lines()
    )


def test_a_group_choice_that_no_longer_fits_deselects_with_a_note(
    catalog: EsiCatalog,
) -> None:
    old = terminal_from_esi(catalog.load("EL3104"))
    old.pdo_groups[0].symbol_indices = [0, 1]
    old.symbol_nodes[1].selected = True
    fresh = terminal_from_esi(catalog.load("EL3104"))
    merged, report = merge_terminal("EL3104", old, fresh)
    assert not merged.symbol_nodes[1].selected
    assert report.choices == [
        "AI Compact Channel {channel} [channels 1,2,3,4] deselected: "
        "not in PDO group 'Standard'"
    ]
    assert report.groups_changed == ["Standard (symbols)"]


def test_cli_regenerate_keeps_a_changed_flag_and_group(
    tmp_path: Path, catalog: EsiCatalog
) -> None:
    out = tmp_path / "terminals"
    with cache_home(tmp_path / "cache"):
        made = run_cli(
            "terminals", "generate", "EL3104", "EL1014", "EL3356-0010",
            "--revision", "0x00100000", *ESI_ARGS, "--out", str(out),
        )  # fmt: skip
        # one failing type writes nothing; the others are written
        assert made.code == 2 and "EL3356-0010 has no revision" in made.err
        assert made.err.splitlines()[-1].startswith(
            "error: generated 2 of 3 types; failed: EL3356-0010: "
        )
        assert sorted(p.name for p in out.glob("*.yaml")) == [
            "EL1014.yaml",
            "EL3104.yaml",
        ]
        made = run_cli(
            "terminals", "generate", "EL3356-0010", *ESI_ARGS, "--out", str(out)
        )
        assert made.code == 0, made.err
        el1014 = read_terminal_file(out / "EL1014.yaml")
        el1014["EL1014"].symbol_nodes[0].selected = False
        write_terminal_file(out / "EL1014.yaml", el1014)
        switched = run_cli(
            "terminals", "select-group", str(out / "EL3104.yaml"), "compact"
        )
        assert switched.code == 0, switched.err
        assert "selected PDO group 'Compact'" in switched.out
        result = run_cli("terminals", "regenerate", str(out), *ESI_ARGS)
    assert result.code == 0, result.err
    assert "EL3104: 1 identity change" in result.out
    assert "  identity: revision_number 0x00100000 -> 0x00110000" in result.out
    assert "EL1014: 1 identity change" in result.out
    assert "EL3356-0010: unchanged" in result.out
    assert "regenerated 3 terminal types; 2 files changed" in result.out
    el3104 = read_terminal_file(out / "EL3104.yaml")["EL3104"]
    assert el3104.identity.revision_number == 0x00110000
    assert el3104.selected_pdo_group == "Compact"
    assert [n.selected for n in el3104.symbol_nodes] == [False, True]
    assert (
        not read_terminal_file(out / "EL1014.yaml")["EL1014"].symbol_nodes[0].selected
    )
    assert (out / "schema.json").is_file()


def test_cli_select_group_flips_flags_and_rejects_unknown_groups(
    tmp_path: Path,
) -> None:
    out = tmp_path / "t"
    with cache_home(tmp_path / "cache"):
        assert (
            run_cli(
                "terminals", "generate", "EL1502", *ESI_ARGS, "--out", str(out)
            ).code
            == 0
        )
    path = out / "EL1502.yaml"
    before = read_terminal_file(path)["EL1502"]
    other = next(g.name for g in before.pdo_groups if not g.is_default)
    switched = run_cli("terminals", "select-group", str(path), other)
    assert switched.code == 0, switched.err
    after = read_terminal_file(path)["EL1502"]
    assert after.selected_pdo_group == other
    assert [n.selected for n in after.symbol_nodes] == [
        not n.selected for n in before.symbol_nodes
    ]
    bad = run_cli("terminals", "select-group", str(path), "Nope")
    assert bad.code == 2
    assert bad.err.startswith(f"error: {path}:EL1502: no PDO group 'Nope' (groups: ")
    assert bad.err.count("\n") == 1
