"""An old generic catalogue next to the real files must not change any choice.

Diamond's ESI folder holds `Beckhoff EtherCAT Terminals.xml`, an old catalogue
whose devices have placeholder revisions (#x270b0000, "-9995", numerically
larger than every real one) and give PDOs only by reference (`<TxPdo Ref=...
Chn=.../>`, no `<Index>`). No such file is among the shared ESI files, so the
test builds one in that documented shape from real devices: the EK1100 and
EL1014 descriptions of the shared files, with the placeholder revision, every
PDO turned into a reference and the CoE dictionary left out. Two passive
devices (no product code, no process data, as end caps and potential feeds
are described in a full catalogue) are made from the real EK1122 the same way.
"""

from __future__ import annotations

import copy
import shutil
from pathlib import Path

import pytest
from lxml import etree

from fastcs_ethercat.esi import build_catalog
from fastcs_ethercat.terminals.files import read_terminal_file

from .conftest import NEEDS_ESI_SUBSET
from .test_terminals_support import ESI, TERMINALS, cache_home, run_cli

PLACEHOLDER = "#x270b0000"
STUB_FILE = "Beckhoff EtherCAT Terminals.xml"
REAL_FILES = ("Beckhoff EK11xx.xml", "Beckhoff EL1xxx.xml")
PASSIVE = ("EL9011", "EL9080")


def _stub(device: etree._Element) -> etree._Element:
    """A real device turned into a catalogue placeholder."""
    stub = copy.deepcopy(device)
    type_element = stub.find("Type")
    assert type_element is not None
    type_element.set("RevisionNo", PLACEHOLDER)
    for child in list(stub):
        if child.tag in ("HideType", "Profile"):
            stub.remove(child)
    for channel, pdo in enumerate(stub.iterfind("TxPdo"), 1):
        reference = pdo.findtext("Index")
        assert reference is not None
        for child in list(pdo):
            pdo.remove(child)
        pdo.attrib.clear()
        pdo.set("Ref", reference)
        pdo.set("Chn", str(channel))
    return stub


def _passive(device: etree._Element, name: str) -> etree._Element:
    """A real device turned into a passive one: no product code, no data."""
    passive = copy.deepcopy(device)
    type_element = passive.find("Type")
    assert type_element is not None
    type_element.text = name
    type_element.attrib.pop("ProductCode")
    for child in list(passive):
        if child.tag in ("Sm", "TxPdo", "RxPdo", "HideType", "Profile"):
            passive.remove(child)
    return passive


def _device(path: Path, type_name: str, revision: str) -> etree._Element:
    root = etree.parse(str(path)).getroot()
    for device in root.iterfind("Descriptions/Devices/Device"):
        found = device.find("Type")
        if (
            found is not None
            and found.text == type_name
            and found.get("RevisionNo", "").lower() == revision
        ):
            return device
    raise AssertionError(f"{type_name} {revision} not in {path}")


@pytest.fixture(scope="module")
def esi_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not ESI.is_dir():
        pytest.skip(NEEDS_ESI_SUBSET)
    folder = tmp_path_factory.mktemp("esi")
    for name in REAL_FILES:
        shutil.copy(ESI / name, folder / name)
    root = etree.parse(str(ESI / "Beckhoff EK11xx.xml")).getroot()
    devices = root.find("Descriptions/Devices")
    assert devices is not None
    for device in list(devices):
        devices.remove(device)
    devices.append(_stub(_device(ESI / REAL_FILES[0], "EK1100", "#x00120000")))
    devices.append(_stub(_device(ESI / REAL_FILES[1], "EL1014", "#x00130000")))
    for passive_name in PASSIVE:
        devices.append(_passive(_device(ESI / REAL_FILES[0], "EK1122", "#x00100000"),
                                passive_name))  # fmt: skip
    etree.ElementTree(root).write(
        str(folder / STUB_FILE), xml_declaration=True, encoding="utf-8"
    )
    return folder


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path):
    with cache_home(tmp_path / "cache"):
        yield


def test_the_catalog_knows_the_placeholders(esi_folder: Path) -> None:
    catalog = build_catalog(esi_folder)
    el1014 = {e.revision: e for e in catalog.revisions("EL1014")}
    stub = el1014[0x270B0000]
    assert stub.problem is not None
    assert "<TxPdo Ref='#x1a00'> only refers to a PDO" in stub.problem
    ek1100 = {e.revision: e for e in catalog.revisions("EK1100")}
    assert ek1100[0x270B0000].parses  # no PDOs to refer to: it parses...
    assert 0x270B0000 in ek1100[0x00000000].hides  # ...but the real file hides it
    assert catalog.find("EK1100").revision == 0x00120000
    assert catalog.find("EL1014").revision == 0x00130000


def test_passive_devices_are_one_line(esi_folder: Path) -> None:
    catalog = build_catalog(esi_folder)
    assert catalog.passive == PASSIVE and catalog.warnings == ()
    listed = run_cli("terminals", "list", "--esi", str(esi_folder))
    assert listed.code == 0
    assert listed.err == (
        "note: 2 passive devices without a product code left out (EL9011, EL9080)\n"
    )


def test_list_marks_what_does_not_parse(esi_folder: Path) -> None:
    listed = run_cli(
        "terminals", "list", "--esi", str(esi_folder), "--filter", "E?1?[01]4"
    )
    assert listed.code == 0, listed.err
    lines = listed.out.splitlines()
    el1014 = next(line for line in lines if line.startswith("EL1014 "))
    assert "revision=0x00130000" in el1014 and el1014.endswith("not-parsed=0x270b0000")
    every = run_cli("terminals", "list", "--esi", str(esi_folder), "--revisions",
                    "--filter", "EK1100")  # fmt: skip
    rows = every.out.splitlines()
    assert any(r.startswith("EK1100 ") and "revision=0x270b0000" in r
               and r.endswith(" hidden") for r in rows)  # fmt: skip
    stub_row = run_cli("terminals", "list", "--esi", str(esi_folder), "--revisions",
                       "--filter", "EL1014")  # fmt: skip
    assert any("revision=0x270b0000" in r and " NOT PARSED: line " in r
               for r in stub_row.out.splitlines())  # fmt: skip


def test_generate_and_show_choose_real_revisions(
    esi_folder: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    made = run_cli("terminals", "generate", "EL1014", "EK1100", "--esi",
                   str(esi_folder), "--out", str(out))  # fmt: skip
    assert made.code == 0, made.err
    assert read_terminal_file(out / "EL1014.yaml")[
        "EL1014"
    ].identity.revision_number == (0x00130000)
    shown = run_cli("terminals", "show", "EK1100", "--esi", str(esi_folder))
    assert shown.code == 0, shown.err
    assert shown.out.startswith("EK1100 revision=0x00120000")
    assert "0x270b0000" in shown.out.splitlines()[3]
    stub = run_cli("terminals", "show", "EL1014", "--esi", str(esi_folder),
                   "--revision", "0x270b0000")  # fmt: skip
    assert stub.code == 2
    error = stub.err.splitlines()[-1]
    assert error.startswith("error: ") and "only refers to a PDO" in error


def test_regenerate_keeps_each_file_in_its_lineage(
    esi_folder: Path, tmp_path: Path
) -> None:
    out = tmp_path / "terminals"
    out.mkdir()
    for name in ("EK1100.yaml", "EL1014.yaml"):
        shutil.copy(TERMINALS / name, out / name)
    result = run_cli("terminals", "regenerate", str(out), "--esi", str(esi_folder))
    assert result.code == 0, result.err
    assert "regenerated 2 terminal types; 0 files changed" in result.out
    for name in ("EK1100.yaml", "EL1014.yaml"):
        assert (out / name).read_bytes() == (TERMINALS / name).read_bytes()
    # only an explicit --revision moves a file to the placeholder
    moved = run_cli("terminals", "regenerate", str(out), "--esi", str(esi_folder),
                    "--revision", "EK1100=0x270b0000")  # fmt: skip
    assert moved.code == 0, moved.err
    ek1100 = read_terminal_file(out / "EK1100.yaml")["EK1100"]
    assert ek1100.identity.revision_number == 0x270B0000
    assert ek1100.esi_file == STUB_FILE
