"""Bad terminal YAML: one line `error: <file>:<line>:<col>: <where>: <what>`, exit 2."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.processes import run_cli_child

from .test_terminals_support import ESI_ARGS, TERMINALS, cache_home, run_cli

GOOD = (TERMINALS / "EL3104.yaml").read_text(encoding="utf-8")


def _line_of(text: str, needle: str) -> int:
    """1-based line of the first line containing `needle`."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def _broken(tmp_path: Path, old: str, new: str, count: int = 1) -> tuple[Path, str]:
    assert old in GOOD
    text = GOOD.replace(old, new, count)
    path = tmp_path / "EL3104.yaml"
    path.write_text(text, encoding="utf-8")
    return path, text


def _check(*paths: Path) -> tuple[int, str]:
    result = run_cli("terminals", "check", *map(str, paths))
    assert result.out == ""
    assert result.err.count("\n") == 1, result.err
    assert "Traceback" not in result.err
    return result.code, result.err.rstrip("\n")


def test_a_good_file_checks(tmp_path: Path) -> None:
    path, _ = _broken(tmp_path, "AnaIn", "AnaIn")
    result = run_cli("terminals", "check", str(path))
    assert (result.code, result.out) == (0, "1 terminal types OK\n")


def test_syntax_error(tmp_path: Path) -> None:
    path, text = _broken(
        tmp_path, "    pdo_indices: [0x1a00, 0x1a02, 0x1a04, 0x1a06]\n    symbol",
        "    pdo_indices: [0x1a00, 0x1a02, 0x1a04, 0x1a06\n    symbol",
    )  # fmt: skip
    code, err = _check(path)
    assert code == 2
    assert err.startswith(f"error: {path}:")
    assert "YAML syntax error" in err
    line = int(err.split(":")[2])
    assert abs(line - _line_of(text, "0x1a04, 0x1a06")) <= 1


def test_wrong_type(tmp_path: Path) -> None:
    path, text = _broken(tmp_path, "    selected: true", "    selected: maybe")
    code, err = _check(path)
    line = _line_of(text, "selected: maybe")
    assert code == 2
    assert err.startswith(
        f"error: {path}:{line}:5: EL3104.symbol_nodes[0].selected: "
        "Input should be a valid boolean"
    )


def test_unknown_key(tmp_path: Path) -> None:
    path, text = _broken(tmp_path, "  group_type: AnaIn", "  group_typ: AnaIn")
    code, err = _check(path)
    line = _line_of(text, "group_typ:")
    assert (code, err) == (
        2,
        f"error: {path}:{line}:3: EL3104.group_typ: unknown key 'group_typ'",
    )


def test_missing_key(tmp_path: Path) -> None:
    path, text = _broken(tmp_path, "    bit_size: 32\n", "")
    code, err = _check(path)
    line = _line_of(text, "- name_template: AI Standard")
    assert (code, err) == (
        2,
        f"error: {path}:{line}:5: EL3104.symbol_nodes[0]: missing key 'bit_size'",
    )


def test_duplicate_key(tmp_path: Path) -> None:
    path, text = _broken(
        tmp_path, "    selected: true\n", "    selected: true\n    selected: false\n"
    )
    code, err = _check(path)
    line = _line_of(text, "selected: false")
    assert (code, err) == (
        2,
        f"error: {path}:{line}:5: duplicate key 'EL3104.symbol_nodes[0].selected'",
    )


def test_inconsistent_selection(tmp_path: Path) -> None:
    path, text = _broken(tmp_path, "    selected: false", "    selected: true")
    code, err = _check(path)
    line = _line_of(text.split("AI Compact Channel")[1], "selected: true")
    line += _line_of(text, "name_template: AI Compact Channel") - 1
    assert code == 2
    assert err == (
        f"error: {path}:{line}:5: EL3104.symbol_nodes[1].selected: selected, but it "
        "belongs only to PDO group(s) ['Compact'], not to the selected group 'Standard'"
    )


def test_bad_hex_and_group_name(tmp_path: Path) -> None:
    path, text = _broken(
        tmp_path, "selected_pdo_group: Standard", "selected_pdo_group: X"
    )
    code, err = _check(path)
    line = _line_of(text, "selected_pdo_group: X")
    assert err == (
        f"error: {path}:{line}:3: EL3104.selected_pdo_group: no PDO group named "
        "'X' (groups: Standard, Compact) (and 1 more problem)"
    )
    path, text = _broken(tmp_path, "product_code: 0x0c203052", "product_code: -1")
    code, err = _check(path)
    line = _line_of(text, "product_code: -1")
    assert code == 2
    assert err.startswith(f"error: {path}:{line}:5: EL3104.identity.product_code: ")


def test_not_a_mapping_and_empty_files(tmp_path: Path) -> None:
    path = tmp_path / "EL3104.yaml"
    path.write_text("- just\n- a list\n", encoding="utf-8")
    assert _check(path) == (
        2,
        f"error: {path}:1:1: expected a mapping of terminal type names to "
        "terminal descriptions",
    )
    path.write_text("", encoding="utf-8")
    assert _check(path)[0] == 2
    path.write_text("'EL 3104': {}\n", encoding="utf-8")
    assert _check(path) == (
        2,
        f"error: {path}:1:1: 'EL 3104' is not a terminal type name "
        "(like EL3104 or EL3356-0010)",
    )


def test_duplicate_types_and_identities(tmp_path: Path) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    one.mkdir()
    two.mkdir()
    shutil.copy(TERMINALS / "EL3104.yaml", one)
    shutil.copy(TERMINALS / "EL3104.yaml", two)
    code, err = _check(one, two)
    assert (code, err) == (
        2,
        f"error: {two / 'EL3104.yaml'}:EL3104: terminal type EL3104 is also "
        f"defined in {one / 'EL3104.yaml'}",
    )
    (two / "EL3104.yaml").write_text(GOOD.replace("\nEL3104:", "\nEL3104-X:"), "utf-8")
    code, err = _check(one, two)
    assert code == 2
    assert "EL3104-X has the same identity (product code 0x0c203052" in err


def test_other_commands_report_bad_files_the_same_way(tmp_path: Path) -> None:
    path, text = _broken(tmp_path, "  group_type: AnaIn", "  group_typ: AnaIn")
    expected = f"error: {path}:{_line_of(text, 'group_typ')}:3: EL3104.group_typ: "
    switched = run_cli("terminals", "select-group", str(path), "Compact")
    assert (switched.code, switched.err.startswith(expected)) == (2, True)
    with cache_home(tmp_path / "cache"):
        regenerated = run_cli("terminals", "regenerate", str(tmp_path), *ESI_ARGS)
    assert (regenerated.code, regenerated.err.startswith(expected)) == (2, True)
    assert path.read_text(encoding="utf-8") == text


@pytest.mark.e2e
def test_the_console_script_prints_one_line(tmp_path: Path) -> None:
    path, text = _broken(tmp_path, "    selected: true", "    selected: maybe")
    done = run_cli_child("terminals", "check", path, timeout=60)
    assert done.returncode == 2
    assert done.stdout == ""
    line = _line_of(text, "selected: maybe")
    assert done.stderr.startswith(f"error: {path}:{line}:5: EL3104.symbol_nodes[0]")
    assert done.stderr.count("\n") == 1


@pytest.mark.parametrize("bad", ["0x1g00", "[0x1a00", "{a: 1"])
def test_odd_scalars_never_traceback(tmp_path: Path, bad: str) -> None:
    path, _ = _broken(tmp_path, "[0x1a00, 0x1a02, 0x1a04, 0x1a06]", bad)
    code, err = _check(path)
    assert code == 2 and err.startswith(f"error: {path}:")
