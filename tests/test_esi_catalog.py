"""Catalog of the real ESI files: counts, terminals, revisions, cache, zip."""

from __future__ import annotations

import re
import shutil
import zipfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi import EsiCatalog, build_catalog
from fastcs_ethercat.esi import catalog as catalog_module
from tests.conftest import DLS_TYPES
from tests.conftest import EL3356_FIXTURE as FIXTURE
from tests.conftest import ESI_SUBSET as ESI

# Devices per file of the full set, from shared/esi/SOURCES.md.
DEVICES_PER_FILE = {
    "Beckhoff EK11xx.xml": 19,
    "Beckhoff EL1xxx.xml": 141,
    "Beckhoff EL15xx.xml": 15,
    "Beckhoff EL2xxx.xml": 119,
    "Beckhoff EL31xx.xml": 48,
    "Beckhoff EL37xx.xml": 5,
    "Beckhoff EL3xxx.xml": 37,
    "2011-08/Beckhoff EL3xxx.xml": 28,
    "Beckhoff EL47xx.xml": 6,
    "Beckhoff EL4xxx.xml": 58,
    "Beckhoff ELM37xx.xml": 1,
    "Beckhoff EP3xxx.xml": 21,
    "Beckhoff EP4xxx.xml": 8,
}


def relative_name(source: str, root: Path = ESI) -> str:
    return Path(source).resolve().relative_to(root.resolve()).as_posix()


@pytest.fixture(scope="module")
def catalog(tmp_path_factory: pytest.TempPathFactory) -> Iterator[EsiCatalog]:
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("xdg-cache")))
        yield build_catalog([ESI, FIXTURE])


def test_every_file_lists_its_documented_device_count(shared_esi: Path) -> None:
    catalog = build_catalog(shared_esi, use_cache=False)
    counts = Counter(relative_name(e.source, shared_esi) for e in catalog.entries)
    assert counts == DEVICES_PER_FILE
    assert catalog.warnings == ()


@pytest.mark.parametrize("type_name", DLS_TYPES)
def test_every_dls_terminal_is_listed(catalog: EsiCatalog, type_name: str) -> None:
    newest = catalog.find(type_name)
    assert newest.type_name == type_name
    assert newest.vendor_id == 2
    assert newest.description.startswith(type_name)


def test_el3356_0010_comes_from_the_fixture(catalog: EsiCatalog) -> None:
    entry = catalog.find("EL3356-0010")
    assert entry.source == str(FIXTURE)
    assert entry.product_code == 0x0D1C3052
    assert entry.has_pdo_groups


def test_revisions_are_listed_oldest_first_and_newest_is_default(
    catalog: EsiCatalog,
) -> None:
    revisions = [entry.revision for entry in catalog.revisions("EL1502")]
    assert revisions == [
        0x00000000, 0x00010000, 0x00100000, 0x00110000, 0x00120000,
        0x00130000, 0x00140000, 0x00150000, 0x00160000,
    ]  # fmt: skip
    assert catalog.find("EL1502").revision == 0x00160000
    assert catalog.find("EL1502", 0x00120000).revision == 0x00120000
    # revision numbers in mixed case in the file: #x03F80000 ... #x03fa0000
    assert [e.revision for e in catalog.revisions("EL4134")] == [
        0x03F80000,
        0x03F90000,
        0x03FA0000,
    ]


def test_an_exact_revision_loads_that_device(catalog: EsiCatalog) -> None:
    old = catalog.load("EL3104", 0x00100000)
    assert (old.type_name, old.revision) == ("EL3104", 0x00100000)
    assert catalog.load("el3104").revision == 0x00110000  # case-insensitive type


def test_unknown_type_or_revision_is_a_user_error(catalog: EsiCatalog) -> None:
    with pytest.raises(UserError, match="EL9999"):
        catalog.find("EL9999")
    with pytest.raises(UserError, match=r"EL3104 has no revision #x00990000.*known"):
        catalog.find("EL3104", 0x00990000)


def test_duplicate_revision_prefers_the_newer_download(catalog: EsiCatalog) -> None:
    # EL3602 #x00100000 is in both EL3xxx.xml copies; the 2018 file (which
    # also holds #x00130000) wins over the 2011 one.
    sources = {
        relative_name(e.source) for e in catalog.entries if e.type_name == "EL3602"
    }
    assert sources == {"Beckhoff EL3xxx.xml", "2011-08/Beckhoff EL3xxx.xml"}
    chosen = catalog.find("EL3602", 0x00100000)
    assert relative_name(chosen.source) == "Beckhoff EL3xxx.xml"
    assert len(catalog.revisions("EL3602")) == 4


def test_catalog_group_flag_and_lines_match_the_full_parse(
    catalog: EsiCatalog,
) -> None:
    for type_name in ("EL3104", "EL1502", "EL2024", "EL3314", "EP3174-0002"):
        for entry in catalog.revisions(type_name):
            device = catalog.load(type_name, entry.revision)
            assert entry.has_pdo_groups == bool(device.pdo_groups)
            assert entry.line == device.source_line
            assert entry.description == device.description


def test_device_lines_are_the_lines_of_the_device_tags(catalog: EsiCatalog) -> None:
    for entry in catalog.revisions("EL3104") + catalog.revisions("ELM3704-0000"):
        lines = Path(entry.source).read_bytes().split(b"\r\n")  # CRLF files
        assert lines[entry.line - 1].strip().startswith(b"<Device")


def _copy_small_files(target: Path) -> Path:
    target.mkdir()
    for name in ("Beckhoff EK11xx.xml", "Beckhoff EL47xx.xml"):
        shutil.copy(ESI / name, target / name)
    return target


def test_second_listing_is_answered_from_the_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    source = _copy_small_files(tmp_path / "esi")
    first = build_catalog(source)
    assert len(first) == 8 + 4  # EK1100 x5, EK1122 x3; EL4732 x4
    assert list((tmp_path / "cache" / "fastcs-ethercat" / "esi-catalog").iterdir())

    def no_scanning(data: bytes, name: str) -> object:
        raise AssertionError(f"scanned {name} although it is cached")

    monkeypatch.setattr(catalog_module, "scan_document", no_scanning)
    second = build_catalog(source)
    assert second.entries == first.entries


def test_changed_content_is_scanned_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    source = _copy_small_files(tmp_path / "esi")
    assert len(build_catalog(source)) == 12
    target = source / "Beckhoff EL47xx.xml"
    data = target.read_bytes()
    starts = [match.start() for match in re.finditer(rb"<Device[\s>]", data)]
    cut = starts[1]  # keep the first device only
    target.write_bytes(data[:cut] + b"</Devices></Descriptions></EtherCATInfo>\r\n")
    again = build_catalog(source)
    assert len(again) == 8 + 1


def test_listing_without_cache_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    build_catalog(_copy_small_files(tmp_path / "esi"), use_cache=False)
    assert not (tmp_path / "cache").exists()


def test_beckhoff_zip_is_a_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    archive = tmp_path / "Beckhoff_EtherCAT_XML.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zipped:
        zipped.write(ESI / "Beckhoff EL15xx.xml", "Beckhoff EL15xx.xml")
        zipped.write(ESI / "Beckhoff EK11xx.xml", "Beckhoff EK11xx.xml")
        zipped.writestr("readme.txt", "not an ESI file")
    for attempt in ("cold", "warm"):
        catalog = build_catalog(archive)
        assert len(catalog) == 10 + 8, attempt  # EL1502 x9, EL1512; EK11xx
        entry = catalog.find("EL1502")
        assert entry.source == f"{archive}!Beckhoff EL15xx.xml"
        device = catalog.load("EL1502")
        assert device.source == entry.source
        assert device.default_group == "1Ch. +/- Counter"


def test_missing_source_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such ESI file or directory"):
        build_catalog(tmp_path / "nowhere", use_cache=False)


def test_corrupt_cache_is_ignored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    source = _copy_small_files(tmp_path / "esi")
    first = build_catalog(source)
    cache_dir = tmp_path / "cache" / "fastcs-ethercat" / "esi-catalog"
    files = sorted(cache_dir.glob("*.json"))
    files[0].write_text("{not json")
    for other in files[1:]:
        other.write_text('{"": [[["EL1", "x"]], []]}')
    assert build_catalog(source).entries == first.entries
