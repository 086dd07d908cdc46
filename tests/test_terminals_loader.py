"""Loading: files, directories, globs; the registry (catio: test_terminals_catio)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import read_terminal_file, write_terminal_file
from fastcs_ethercat.terminals.loader import load_terminals, terminal_paths
from fastcs_ethercat.terminals.registry import variant_of

from .test_terminals_support import TERMINALS


@pytest.fixture
def terminals_copy(tmp_path: Path) -> Path:
    copy = tmp_path / "terminals"
    shutil.copytree(TERMINALS, copy)
    return copy


def test_directory_file_and_glob_sources(terminals_copy: Path) -> None:
    everything = terminal_paths([terminals_copy])
    assert len(everything) == 20 and all(p.suffix == ".yaml" for p in everything)
    analog_in = terminal_paths([str(terminals_copy / "EL31*.yaml")])
    assert [p.stem for p in analog_in] == ["EL3104", "EL3124"]
    mixed = load_terminals(
        [terminals_copy / "EL1014.yaml", str(terminals_copy / "EL31*.yaml")]
    )
    assert mixed.type_names() == ["EL1014", "EL3104", "EL3124"]
    again = terminal_paths([terminals_copy / "EL1014.yaml", terminals_copy])
    assert again.count(terminals_copy / "EL1014.yaml") == 1


def test_missing_sources_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no terminal YAML files match"):
        terminal_paths([str(tmp_path / "*.yaml")])
    with pytest.raises(UserError, match="no such terminal YAML file"):
        terminal_paths([tmp_path / "EL9999.yaml"])


def test_registry_exact_and_nearest_revision(terminals_copy: Path) -> None:
    el3104 = read_terminal_file(terminals_copy / "EL3104.yaml")["EL3104"]
    registry = load_terminals([str(terminals_copy / "EL3*.yaml")])
    code = el3104.identity.product_code
    exact = registry.lookup(code, 0x00110000)
    assert exact is not None and exact.exact and exact.type_name == "EL3104"
    newer = registry.lookup(code, 0x00150000, vendor_id=2)
    assert newer is not None and not newer.exact and newer.type_name == "EL3104"
    assert newer.requested_revision == 0x00150000
    older = registry.lookup(code, 0x00100000)  # only a newer one is known
    assert older is not None and not older.exact and older.revision == 0x00110000
    assert registry.lookup(code, 0x00150000, vendor_id=7) is None
    assert registry.lookup(0x12345678, 0x00110000) is None


def test_nearest_revision_prefers_the_variant(tmp_path: Path) -> None:
    el3356 = read_terminal_file(TERMINALS / "EL3356-0010.yaml")
    assert variant_of(el3356["EL3356-0010"].identity.revision_number) == 10
    plain = el3356["EL3356-0010"].model_copy(deep=True)
    plain.identity.revision_number = 0x00110000
    write_terminal_file(tmp_path / "EL3356-0010.yaml", el3356)
    write_terminal_file(tmp_path / "EL3356.yaml", {"EL3356": plain})
    registry = load_terminals([tmp_path])
    code = plain.identity.product_code
    ten = registry.lookup(code, 0x0014000A)
    assert ten is not None and ten.type_name == "EL3356-0010" and not ten.exact
    zero = registry.lookup(code, 0x00140000)
    assert zero is not None and zero.type_name == "EL3356"
    only_ten = load_terminals([tmp_path / "EL3356-0010.yaml"])
    other = only_ten.lookup(code, 0x00140000)  # no YAML of variant 0 at all
    assert other is not None and other.type_name == "EL3356-0010"
    assert not other.exact


def test_nearest_revision_in_either_direction(tmp_path: Path) -> None:
    el3104 = read_terminal_file(TERMINALS / "EL3104.yaml")["EL3104"]
    types = {}
    for revision in (0x00100000, 0x00140000):
        copy = el3104.model_copy(deep=True)
        copy.identity.revision_number = revision
        types[f"EL3104-R{revision >> 16:X}"] = copy
    write_terminal_file(tmp_path / "EL3104.yaml", types)
    registry = load_terminals([tmp_path])
    code = el3104.identity.product_code

    def nearest(revision: int) -> int:
        match = registry.lookup(code, revision)
        assert match is not None
        return match.revision

    assert nearest(0x000F0000) == 0x00100000  # older than every YAML
    assert nearest(0x00110000) == 0x00100000
    assert nearest(0x00120000) == 0x00100000  # a tie: the older
    assert nearest(0x00130000) == 0x00140000
    assert nearest(0x00200000) == 0x00140000  # newer than every YAML


def test_registry_refuses_duplicates(terminals_copy: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(terminals_copy / "EL3104.yaml", other / "EL3104.yaml")
    analog = str(terminals_copy / "EL31*.yaml")
    with pytest.raises(UserError, match="terminal type EL3104 is also defined in"):
        load_terminals([analog, other])
    el3104 = read_terminal_file(terminals_copy / "EL3104.yaml")["EL3104"]
    write_terminal_file(other / "EL3104.yaml", {"EL3104-COPY": el3104})
    with pytest.raises(UserError, match="has the same identity"):
        load_terminals([analog, other])


def test_a_type_may_be_described_at_several_revisions(
    terminals_copy: Path, tmp_path: Path
) -> None:
    el3104 = read_terminal_file(terminals_copy / "EL3104.yaml")["EL3104"]
    older = el3104.model_copy(deep=True)
    older.identity.revision_number = 0x00100000
    other = el3104.model_copy(deep=True)
    other.identity.product_code = 0x12345678
    site = tmp_path / "site"
    site.mkdir()
    write_terminal_file(site / "EL3104.yaml", {"EL3104": older})
    registry = load_terminals([site, terminals_copy / "EL3104.yaml"])
    code = el3104.identity.product_code

    assert registry.get("EL3104").terminal.identity.revision_number == 0x00100000
    assert len(registry) == 2 and registry.type_names() == ["EL3104"]
    for revision in (0x00100000, 0x00110000):
        match = registry.lookup(code, revision)
        assert match is not None and match.exact and match.revision == revision
    write_terminal_file(site / "EL3104.yaml", {"EL3104": other})
    with pytest.raises(UserError, match="with another product code"):
        load_terminals([site, terminals_copy / "EL3104.yaml"])
