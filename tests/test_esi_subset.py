"""The ESI the tests ship is the real files cut, and its README says so."""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

from tests.conftest import ESI_SUBSET, NEEDS_ESI_SUBSET, REPO_ROOT
from tests.esi_subset import DLS_TYPES, QUIRKS, cut, device_spans, sha256, wanted

README = ESI_SUBSET.parent / "README.md"


def readme_rows() -> dict[str, list[str]]:
    """The provenance table: file -> its cells (commit, sha256, sizes, kept)."""
    rows = {}
    for line in README.read_text(encoding="utf-8").splitlines():
        cells = [cell.strip().strip("`") for cell in line.strip("|").split("|")]
        if len(cells) == 6 and cells[0].endswith(".xml"):
            rows[cells[0]] = cells[1:]
    return rows


def shipped() -> dict[str, Path]:
    return {p.relative_to(ESI_SUBSET).as_posix(): p for p in ESI_SUBSET.rglob("*.xml")}


def test_every_shipped_file_is_its_source_cut(shared_esi: Path) -> None:
    sources = {
        p.relative_to(shared_esi).as_posix(): p for p in shared_esi.rglob("*.xml")
    }
    assert sources.keys() == shipped().keys()
    for name, source in sources.items():
        data = source.read_bytes()
        assert cut(data, name)[0] == shipped()[name].read_bytes(), name
        assert readme_rows()[name][1] == sha256(data), name


def test_shipped_files_hold_exactly_the_chosen_devices() -> None:
    found: set[tuple[str, int]] = set()
    for name, path in shipped().items():
        spans = device_spans(path.read_bytes(), name)
        assert all(wanted(s.type_name, s.revision) for s in spans), name
        found |= {(span.type_name, span.revision) for span in spans}
    assert {type_name for type_name, _ in found} >= DLS_TYPES
    assert found >= QUIRKS


def test_the_readme_lists_every_file_with_its_size() -> None:
    rows = readme_rows()
    assert rows.keys() == shipped().keys()
    for name, path in shipped().items():
        commit, digest, _, size, _ = rows[name]
        assert re.fullmatch(r"[0-9a-f]{7}", commit) and re.fullmatch(
            r"[0-9a-f]{64}", digest
        )
        assert int(size) == path.stat().st_size, name


def esi_skips() -> Iterator[tuple[str, str, str]]:
    """(where, condition, reason) of every skip in tests/ whose condition
    looks at ESI files: `if not X.is_dir(): pytest.skip(...)` and
    `pytest.mark.skipif(not X.is_dir(), reason=...)`."""
    for path in sorted((REPO_ROOT / "tests").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        parents = {
            child: node
            for node in ast.walk(tree)
            for child in ast.iter_child_nodes(node)
        }
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            called = ast.unparse(node.func)
            if called == "pytest.mark.skipif":
                condition = ast.unparse(node.args[0])
                reason = next(k.value for k in node.keywords if k.arg == "reason")
            elif called == "pytest.skip":
                branch = parents[parents[node]]
                if not isinstance(branch, ast.If):
                    continue
                condition, reason = ast.unparse(branch.test), node.args[0]
            else:
                continue
            if "ESI" in condition:
                yield f"{path.name}:{node.lineno}", condition, ast.unparse(reason)


def test_a_skip_for_want_of_esi_names_the_files_it_checks() -> None:
    """The subset is committed (a plain clone has it); only the full set is
    in ../shared/esi: a skip must not send a user looking for the wrong one."""
    skips = list(esi_skips())
    subset = [s for s in skips if "SHARED_ESI" not in s[1]]
    full = [s for s in skips if "SHARED_ESI" in s[1]]

    assert {where.split(":")[0] for where, _, _ in subset} >= {
        "test_editor_browser.py",
        "test_editor_session.py",
        "test_esi_catalogue_stubs.py",
        "test_terminals_catio.py",
        "test_terminals_support.py",
    }
    assert [(w, r) for w, _, r in subset if r != "NEEDS_ESI_SUBSET"] == []
    assert all("shared/esi" in reason for _, _, reason in full)
    assert "tests/data/esi/beckhoff" in NEEDS_ESI_SUBSET
    assert ESI_SUBSET == REPO_ROOT / "tests" / "data" / "esi" / "beckhoff"
