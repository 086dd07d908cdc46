"""The ESI the tests ship is the real files cut, and its README says so."""

from __future__ import annotations

import re
from pathlib import Path

from tests.conftest import ESI_SUBSET
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
