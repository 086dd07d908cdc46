"""The committed terminals/ directory: complete, byte-stable, and what the CLI makes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.terminals.files import read_terminal_file, terminal_file_text
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.saving import file_text
from fastcs_ethercat.terminals.schema import schema_text, terminal_schema
from fastcs_ethercat.terminals.yaml_io import SCHEMA_HEADER
from tests.conftest import DLS_TYPES

from .test_terminals_support import ESI_ARGS, TERMINALS, cache_home, run_cli

YAML_FILES = sorted(TERMINALS.glob("*.yaml"))


def test_every_dls_terminal_has_a_file() -> None:
    assert [p.stem for p in YAML_FILES] == sorted(DLS_TYPES)


@pytest.mark.parametrize("path", YAML_FILES, ids=lambda p: p.stem)
def test_load_then_save_is_byte_identical(path: Path) -> None:
    """A save (which carries comments over, as the CLI's and the editor's do)
    writes the file back byte for byte; without comments, so does the plain
    canonical text (EL3356-0010 says in comments where its facts come from)."""
    original = path.read_bytes()
    types = read_terminal_file(path)
    assert list(types) == [path.stem]
    text, dropped = file_text(types, original.decode("utf-8"))
    assert text.encode("utf-8") == original and dropped == []
    lines = original.decode("utf-8").splitlines(keepends=True)
    uncommented = lines[:1] + [line for line in lines[1:] if not line.startswith("#")]
    assert terminal_file_text(types) == "".join(uncommented)


@pytest.mark.parametrize("path", YAML_FILES, ids=lambda p: p.stem)
def test_files_point_editors_at_the_schema(path: Path) -> None:
    assert path.read_text(encoding="utf-8").startswith(SCHEMA_HEADER)


def test_schema_json_is_the_models_schema() -> None:
    written = (TERMINALS / "schema.json").read_text(encoding="utf-8")
    assert written == schema_text()
    schema = json.loads(written)
    terminal = schema["$defs"]["TerminalType"]
    assert {"identity", "symbol_nodes", "coe_objects"} <= set(terminal["required"])
    assert schema["additionalProperties"] == {"$ref": "#/$defs/TerminalType"}
    assert terminal_schema()["$defs"]["SymbolNode"]["additionalProperties"] is False


def test_the_directory_loads_as_a_registry() -> None:
    registry = load_terminals([TERMINALS])
    assert registry.type_names() == sorted(DLS_TYPES)
    match = registry.lookup(0x0C203052, 0x00110000)
    assert match is not None and match.type_name == "EL3104" and match.exact


def test_regenerating_the_committed_files_changes_nothing(tmp_path: Path) -> None:
    """The files are exactly what `terminals regenerate` makes from the ESI."""
    copy = tmp_path / "terminals"
    shutil.copytree(TERMINALS, copy)
    with cache_home(tmp_path / "cache"):
        result = run_cli("terminals", "regenerate", str(copy), *ESI_ARGS)
    assert result.code == 0, result.err
    assert f"regenerated {len(DLS_TYPES)} terminal types; 0 files changed" in result.out
    for path in YAML_FILES:
        assert (copy / path.name).read_bytes() == path.read_bytes()
    assert result.out.count(": unchanged") == len(DLS_TYPES)
