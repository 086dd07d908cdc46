"""The editor's state without a browser: choices, diff, save, search, PV names."""

from __future__ import annotations

import shutil
from functools import partial
from pathlib import Path

import pytest

from fastcs_ethercat.editor.pv_preview import preview_pvs
from fastcs_ethercat.editor.session import EditorSession
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import read_terminal_file
from fastcs_ethercat.terminals.selection import select_coe, select_group
from tests.processes import run_python_child

from .conftest import NEEDS_ESI_SUBSET
from .test_terminals_support import ESI, TERMINALS, cache_home


@pytest.fixture
def session(tmp_path: Path) -> EditorSession:
    folder = tmp_path / "terminals"
    shutil.copytree(TERMINALS, folder)
    return EditorSession(folder, [ESI])


def test_nothing_is_written_before_save_and_an_unchanged_save_is_a_no_op(
    session: EditorSession,
) -> None:
    path = session.directory / "EL3104.yaml"
    before = path.read_bytes()
    assert session.diff("EL3104") == ""
    assert not session.save("EL3104").changed
    session.apply("EL3104", partial(select_group, group_name="Compact"))
    session.apply("EL3104", partial(select_coe, targets=["0x8000"]))
    assert session.types["EL3104"].changed and path.read_bytes() == before
    diff = session.diff("EL3104")
    assert "-  selected_pdo_group: Standard\n+  selected_pdo_group: Compact" in diff
    saved = session.save("EL3104")
    assert saved.changed and not session.types["EL3104"].changed
    terminal = read_terminal_file(path)["EL3104"]
    assert terminal.selected_pdo_group == "Compact"
    session.revert("EL3104")
    assert session.diff("EL3104") == ""


def test_search_and_add_from_the_catalog(
    session: EditorSession, tmp_path: Path
) -> None:
    if not ESI.is_dir():
        pytest.skip(NEEDS_ESI_SUBSET)
    with cache_home(tmp_path / "cache"):
        by_words = [e.type_name for e in session.search("ana. output 16bit")]
        assert "EL4134" in by_words
        assert [e.type_name for e in session.search("EL3102")] == ["EL3102"]
        added = session.add_type("el3102")
        path = session.directory / "EL3102.yaml"
        assert added.name == "EL3102" and added.new and not path.exists()
        default = added.current.default_group
        assert default and added.current.selected_pdo_group == default.name
        with pytest.raises(UserError, match=r"EL3102\.yaml exists already"):
            session.add_type("EL3102")
        session.revert("EL3102")  # discarded: gone, nothing written
        assert "EL3102" not in session.types and not path.exists()
        session.add_type("EL3102")
        assert session.save("EL3102").changed and path.is_file()
        assert not session.get("EL3102").new and not session.get("EL3102").changed
        with pytest.raises(UserError, match=r"EL3104\.yaml exists already"):
            session.add_type("EL3104")


def test_the_preview_names_the_pvs_as_the_ioc_does() -> None:
    el3104 = read_terminal_file(TERMINALS / "EL3104.yaml")["EL3104"]
    pvs = [p.pv for p in preview_pvs(el3104, "EL3104", "DEMO:ETH1:RIO21:MOD22")]
    assert len(pvs) == 41 and "DEMO:ETH1:RIO21:MOD22:CH1:Error" in pvs
    assert "DEMO:ETH1:RIO21:MOD22:C8000:EnableFilter" in pvs  # the shipped CoE
    assert "DEMO:ETH1:RIO21:MOD22:CH1:ValueRaw" in pvs  # volts, and counts
    longest = "BL45P-MO-IOC-01-LONGER:ETH1:RIO1:MOD112"  # the longest prefix
    long = preview_pvs(el3104, "EL3104", longest)
    assert all(p.longest <= 60 for p in long)
    assert not any(p.shortened for p in long if p.node is not None)  # symbols
    el1502 = read_terminal_file(TERMINALS / "EL1502.yaml")["EL1502"]
    counter = {
        p.source.rpartition(".")[2]: p for p in preview_pvs(el1502, "EL1502", longest)
    }
    enable = counter["Enable output functions"]
    assert enable.pv.endswith(":MOD112:EnblOtptFnctns") and enable.longest <= 60
    assert enable.shortened == "vowels dropped to fit 15 characters"
    with pytest.raises(UserError, match="type a terminal's PV prefix"):
        preview_pvs(el3104, "EL3104", "BL45P-MO-IOC-01")


@pytest.mark.e2e
def test_the_ioc_never_imports_the_editor() -> None:
    code = (
        "import sys, fastcs_ethercat.cli, fastcs_ethercat.ioc.app\n"
        "bad = [m for m in sys.modules if m.startswith(('nicegui', "
        "'fastcs_ethercat.editor', 'selenium'))]\n"
        "assert not bad, bad\n"
    )
    done = run_python_child(code)
    assert done.returncode == 0, done.stderr


def test_without_esi_a_plain_clone_adds_types_from_the_subset_it_ships(
    tmp_path: Path,
) -> None:
    """No `--esi` and no cached vendor zip: the checkout's ESI subset."""
    folder = tmp_path / "terminals"
    folder.mkdir()
    with cache_home(tmp_path / "empty-cache"):
        session = EditorSession(folder, None)
        assert [e.type_name for e in session.search("EL4134")] == ["EL4134"]
        added = session.add_type("EL3356-0010")  # from the fixture beside it
        assert added.new and not (folder / "EL3356-0010.yaml").exists()
