"""`fastcs-ethercat terminals ...` against the real ESI files."""

from __future__ import annotations

import json
import re
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from fastcs_ethercat.terminals.files import read_terminal_file
from fastcs_ethercat.terminals.schema import schema_text
from tests.conftest import DLS_TYPES
from tests.processes import run_cli_child

from .test_terminals_support import (
    ESI,
    ESI_ARGS,
    FIXTURE,
    cache_home,
    run_cli,
)

LIST_LINE = re.compile(
    r"^(\S+) +revision=0x[0-9a-f]{8} product_code=0x[0-9a-f]{8} "
    r"group_type=\S+ pdo_groups=(yes|no)$"
)


@pytest.fixture(scope="module", autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Catalog cache and ESI zip cache of these tests stay in a temp dir."""
    home = tmp_path_factory.mktemp("xdg-cache")
    with cache_home(home):
        yield home


def test_list_prints_one_line_per_type_and_a_count() -> None:
    result = run_cli("terminals", "list", *ESI_ARGS)
    assert result.code == 0, result.err
    *lines, count = result.out.splitlines()
    assert all(LIST_LINE.match(line) for line in lines)
    assert count == f"{len(lines)} terminal types"
    names = [line.split()[0] for line in lines]
    assert set(DLS_TYPES) <= set(names) and len(names) == len(set(names))
    el3104 = next(line for line in lines if line.startswith("EL3104 "))
    assert el3104.split()[1:] == [
        "revision=0x00110000",
        "product_code=0x0c203052",
        "group_type=AnaIn",
        "pdo_groups=yes",
    ]


def test_list_filter() -> None:
    result = run_cli("terminals", "list", "--esi", str(ESI), "--filter", "el10?4")
    assert result.code == 0, result.err
    names = [line.split()[0] for line in result.out.splitlines()[:-1]]
    assert "EL1014" in names and "EL1084" in names
    assert all(re.fullmatch(r"EL10.4", n) for n in names)
    assert result.out.splitlines()[-1] == f"{len(names)} terminal types"


def test_show_marks_the_default_group() -> None:
    result = run_cli("terminals", "show", "EL3104", "--esi", str(ESI))
    assert result.code == 0, result.err
    out = result.out
    assert out.startswith("EL3104 revision=0x00110000 product_code=0x0c203052")
    assert "  revisions: 0x00100000, 0x00110000" in out
    assert "PDOs (8):" in out and "  0x1a01 input  AI Compact Channel 1 " in out
    assert "  * Standard (default): 0x1a00 0x1a02 0x1a04 0x1a06" in out
    assert "    Compact: 0x1a01 0x1a03 0x1a05 0x1a07" in out
    assert "  [x] AI Standard Channel {channel} channels 1,2,3,4:" in out
    assert "  [ ] AI Compact Channel {channel} channels 1,2,3,4: INT" in out
    assert "  0x8000 AI Settings (DT8000, rw, 16 sub-items)" in out


def test_show_an_older_revision_and_oversampling() -> None:
    old = run_cli(
        "terminals", "show", "el3104", "--esi", str(ESI), "--revision", "#x00100000"
    )
    assert old.code == 0 and "EL3104 revision=0x00100000" in old.out
    el3702 = run_cli("terminals", "show", "EL3702", "--esi", str(ESI))
    assert "Oversampling: factors 1, 2, 3, 4, 5, 8, 10" in el3702.out
    assert "default 10" in el3702.out


def test_show_unknown_type_or_revision_is_one_line() -> None:
    missing = run_cli("terminals", "show", "EL9999", "--esi", str(ESI))
    assert missing.code == 2 and missing.err.count("\n") == 1
    assert "no ESI description of terminal type 'EL9999'" in missing.err
    bad = run_cli("terminals", "show", "EL3104", "--esi", str(ESI), "--revision", "new")
    assert bad.code == 2 and "--revision 'new' is not a number" in bad.err
    absent = run_cli("terminals", "show", "EL3104", "--revision", "0x5")
    assert absent.code == 2 and "no ESI source" in absent.err


def test_generate_several_types_from_several_sources(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = run_cli("terminals", "generate", "EL3356-0010", "EL3104", *ESI_ARGS,
                     "--out", str(out))  # fmt: skip
    assert result.code == 0, result.err
    assert sorted(p.name for p in out.iterdir()) == [
        "EL3104.yaml",
        "EL3356-0010.yaml",
        "schema.json",
    ]
    assert (out / "schema.json").read_text(encoding="utf-8") == schema_text()
    el3356 = read_terminal_file(out / "EL3356-0010.yaml")["EL3356-0010"]
    assert el3356.esi_file == FIXTURE.name
    again = run_cli(
        "terminals", "generate", "EL3104", "--esi", str(ESI), "--out", str(out)
    )
    assert again.code == 2 and "EL3104.yaml exists" in again.err
    kept = run_cli("terminals", "generate", "EL3104", "--esi", str(ESI),
                   "--out", str(out), "--skip-existing")  # fmt: skip
    assert kept.code == 0 and kept.out.startswith("kept ")


def test_schema_to_stdout_and_file(tmp_path: Path) -> None:
    printed = run_cli("terminals", "schema")
    assert printed.code == 0 and printed.out == schema_text()
    assert json.loads(printed.out)["title"] == "fastcs-ethercat terminal types"
    target = tmp_path / "schema.json"
    written = run_cli("terminals", "schema", "--out", str(target))
    assert written.code == 0 and target.read_text(encoding="utf-8") == schema_text()


def test_update_cache_fails_in_one_line_without_a_network(
    private_cache: Path,
) -> None:
    result = run_cli("terminals", "update-cache", "--url", "http://127.0.0.1:9/")
    assert result.code == 2
    assert result.err.startswith("error: cannot download http://127.0.0.1:9/: ")
    assert result.err.count("\n") == 1
    assert not (
        private_cache / "fastcs-ethercat" / "esi" / "Beckhoff_EtherCAT_XML.zip"
    ).exists()


def test_update_cache_from_a_local_file_then_use_it(
    private_cache: Path, tmp_path: Path
) -> None:
    archive = tmp_path / "Beckhoff_EtherCAT_XML.zip"
    with zipfile.ZipFile(archive, "w") as zipped:
        zipped.write(ESI / "Beckhoff EK11xx.xml", "Beckhoff EK11xx.xml")
    result = run_cli("terminals", "update-cache", "--url", archive.as_uri())
    cached = private_cache / "fastcs-ethercat" / "esi" / "Beckhoff_EtherCAT_XML.zip"
    assert result.code == 0, result.err
    assert result.out == f"cached {cached}\n"
    listed = run_cli("terminals", "list")
    assert listed.code == 0, listed.err
    names = [line.split()[0] for line in listed.out.splitlines()[:-1]]
    assert "EK1100" in names and "EK1122" in names and "EL3104" not in names
    cached.unlink()


@pytest.mark.e2e
def test_update_cache_subprocess_network_failure(tmp_path: Path) -> None:
    done = run_cli_child("terminals", "update-cache", "--url", "http://127.0.0.1:9/",
                         env={"XDG_CACHE_HOME": str(tmp_path), "PATH": "/usr/bin:/bin"},
                         timeout=60)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.startswith("error: cannot download http://127.0.0.1:9/")
    assert done.stderr.count("\n") == 1
