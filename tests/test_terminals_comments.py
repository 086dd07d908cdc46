"""Comments and blank lines an engineer wrote survive every rewrite of a file."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.terminals.comments import carry_comments
from fastcs_ethercat.terminals.files import read_terminal_file, terminal_file_text

from .test_terminals_support import (
    TERMINALS,
    needs_esi,
    regenerated_old_el3104,
    run_cli,
)

LARGE_FILE_LINES = 5_000
"""Over this a file's round trip through ruamel takes 25-40 s (ELM3704-0000,
22 000 lines): `slow`, by the marker's rule."""


def shipped_file_names() -> list[object]:
    return [
        pytest.param(
            path.name,
            marks=[pytest.mark.slow, pytest.mark.e2e]
            if path.read_text(encoding="utf-8").count("\n") > LARGE_FILE_LINES
            else [],
        )
        for path in sorted(TERMINALS.glob("*.yaml"))
    ]


NOTES = {
    "  identity:\n": "  # EL3104s on BL45P run firmware 0x0011 since 2019\n",
    "  selected_pdo_group: Standard\n": "\n# Standard: the MPS needs the status bits\n",
}
TRAILING = ("  - index: 0x8000\n", "  - index: 0x8000  # filter set by hand\n")


def annotated(text: str) -> str:
    for line, note in NOTES.items():
        text = text.replace(line, note + line, 1)
    return text.replace(*TRAILING, 1)


@needs_esi
def test_regenerate_keeps_comments_of_an_older_revision_file(tmp_path: Path) -> None:
    def annotate(path: Path) -> None:
        path.write_text(annotated(path.read_text(encoding="utf-8")), encoding="utf-8")

    path, result = regenerated_old_el3104(
        tmp_path / "terminals", tmp_path / "cache", annotate
    )
    assert result.code == 0, result.err
    assert "EL3104: 1 identity change" in result.out and "dropped" not in result.out
    text = path.read_text(encoding="utf-8")
    assert "revision_number: 0x00110000" in text
    for note in NOTES.values():
        assert note in text
    assert TRAILING[1] in text
    fresh = read_terminal_file(path)
    assert text == annotated(terminal_file_text(fresh))


def test_choices_keep_comments_and_a_plain_file_stays_byte_identical(
    tmp_path: Path,
) -> None:
    path = tmp_path / "EL3104.yaml"
    original = annotated((TERMINALS / "EL3104.yaml").read_text(encoding="utf-8"))
    path.write_text(original, encoding="utf-8")
    assert run_cli("terminals", "select-group", str(path), "Compact").code == 0
    assert run_cli("terminals", "coe", str(path), "0x8010").code == 0
    assert run_cli("terminals", "coe", str(path), "--off", "0x8010").code == 0
    assert run_cli("terminals", "select-group", str(path), "Standard").code == 0
    assert path.read_text(encoding="utf-8") == original
    plain = tmp_path / "EL1014.yaml"
    shutil.copy(TERMINALS / "EL1014.yaml", plain)
    assert run_cli("terminals", "select", str(plain), "--off", "Channel {channel}")
    assert run_cli("terminals", "select", str(plain), "Channel {channel}").code == 0
    assert plain.read_bytes() == (TERMINALS / "EL1014.yaml").read_bytes()


@pytest.mark.parametrize("name", shipped_file_names())
def test_every_shipped_file_round_trips_through_the_comment_keeper(name: str) -> None:
    text = (TERMINALS / name).read_text(encoding="utf-8")
    noted = text.replace("\n  symbol_nodes:\n", "\n  # symbols\n  symbol_nodes:\n", 1)
    assert carry_comments(noted, text) == (noted, [])


def test_a_comment_whose_key_is_gone_is_named(tmp_path: Path) -> None:
    text = (TERMINALS / "EL3104.yaml").read_text(encoding="utf-8")
    line = "    fastcs_name: ai_compact_channel_{channel}"
    old = text.replace(f"{line}\n", f"{line}  # keep\n")
    terminal = read_terminal_file(TERMINALS / "EL3104.yaml")["EL3104"]
    del terminal.symbol_nodes[1]
    terminal.pdo_groups[1].symbol_indices = []
    new = terminal_file_text({"EL3104": terminal})
    kept, dropped = carry_comments(old, new)
    assert kept == new
    assert [str(d) for d in dropped] == [
        "line 96: comment '# keep' dropped (EL3104.symbol_nodes[1].fastcs_name is gone)"
    ]
