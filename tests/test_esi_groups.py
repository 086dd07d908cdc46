"""PDO groups of the real devices: AlternativeSmMapping and Exclude graphs."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from fastcs_ethercat.esi import EsiCatalog, EsiDevice, build_catalog
from fastcs_ethercat.esi.groups import groups_from_excludes
from tests.conftest import EL3356_FIXTURE as FIXTURE
from tests.conftest import ESI_SUBSET as ESI


@pytest.fixture(scope="module")
def catalog(tmp_path_factory: pytest.TempPathFactory) -> Iterator[EsiCatalog]:
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("xdg-cache")))
        yield build_catalog([ESI, FIXTURE])


def groups(device: EsiDevice) -> dict[str, tuple[int, ...]]:
    return {group.name: group.pdo_indices for group in device.pdo_groups}


def test_el3104_standard_and_compact(catalog: EsiCatalog) -> None:
    device = catalog.load("EL3104")
    assert device.revision == 0x00110000
    assert groups(device) == {
        "Standard": (0x1A00, 0x1A02, 0x1A04, 0x1A06),
        "Compact": (0x1A01, 0x1A03, 0x1A05, 0x1A07),
    }
    assert device.default_group == "Standard"
    standard = device.group("Standard")
    assert standard.is_default and standard.origin == "alternative_sm_mapping"
    assert standard.sm_pdos == {3: (0x1A00, 0x1A02, 0x1A04, 0x1A06)}
    names = [device.pdo(i).name for i in device.group("Compact").pdo_indices]
    assert names == [f"AI Compact Channel {n}" for n in (1, 2, 3, 4)]


def test_el1502_newest_has_its_two_mappings(catalog: EsiCatalog) -> None:
    device = catalog.load("EL1502")
    assert device.revision == 0x00160000
    assert groups(device) == {
        "1Ch. +/- Counter": (0x1602, 0x1A02),
        "2Ch. Counter": (0x1600, 0x1601, 0x1A00, 0x1A01),
    }
    # The file makes the combined counter the default (the design document
    # guessed per-channel): Default="1" and the Sm attributes agree.
    assert device.default_group == "1Ch. +/- Counter"
    assert device.group("2Ch. Counter").sm_pdos == {
        2: (0x1600, 0x1601),
        3: (0x1A00, 0x1A01),
    }


def test_el1502_old_revision_groups_come_from_excludes(catalog: EsiCatalog) -> None:
    device = catalog.load("EL1502", 0x00140000)  # no AlternativeSmMapping yet
    assert groups(device) == {
        "Combined": (0x1A02, 0x1602),
        "Per-Channel": (0x1A00, 0x1A01, 0x1600, 0x1601),
    }
    assert device.default_group == "Combined"  # the PDOs with an Sm attribute
    assert {g.origin for g in device.pdo_groups} == {"exclude"}
    assert device.group("Per-Channel").sm_pdos == {
        2: (0x1600, 0x1601),
        3: (0x1A00, 0x1A01),
    }


@pytest.mark.parametrize(
    ("type_name", "revision"),
    [
        ("EL3104", 0x00100000),
        ("EL3104", 0x00110000),
        ("EL3124", 0x00110000),
        ("EL1502", 0x00150000),
        ("EL1502", 0x00160000),
        ("EL1512", 0x00150000),
    ],
)
def test_exclude_rule_reproduces_the_vendor_mappings(
    catalog: EsiCatalog, type_name: str, revision: int
) -> None:
    device = catalog.load(type_name, revision)
    derived = groups_from_excludes(device.pdos, device.sync_managers)
    assert {(frozenset(g.pdo_indices), g.is_default) for g in derived} == {
        (frozenset(g.pdo_indices), g.is_default) for g in device.pdo_groups
    }


def test_exclude_rule_names_standard_and_compact(catalog: EsiCatalog) -> None:
    device = catalog.load("EL3104")
    derived = groups_from_excludes(device.pdos, device.sync_managers)
    assert [(g.name, g.is_default) for g in derived] == [
        ("Standard", True),
        ("Compact", False),
    ]


def test_el31x2_exclude_graph_keeps_uniform_alternatives(catalog: EsiCatalog) -> None:
    # One component of 7 PDOs; per-channel mixes of Standard and Compact are
    # dropped, leaving the vendor's four mappings. The vendor's default
    # (Standard) differs from the Sm attributes (Legacy "Channel n").
    device = catalog.load("EL3102", 0x00110000)
    derived = groups_from_excludes(device.pdos, device.sync_managers)
    assert {frozenset(g.pdo_indices) for g in derived} == {
        frozenset(g.pdo_indices) for g in device.pdo_groups
    }
    assert device.default_group == "Standard"
    assert [g.pdo_indices for g in derived if g.is_default] == [(0x1A00, 0x1A01)]


@pytest.mark.parametrize("type_name", ["EP3174-0002", "EP4374-0002"])
def test_ep_boxes_group_by_excludes_only(catalog: EsiCatalog, type_name: str) -> None:
    device = catalog.load(type_name)
    assert [(g.name, g.is_default, g.origin) for g in device.pdo_groups] == [
        ("Standard", True, "exclude"),
        ("Compact", False, "exclude"),
    ]
    standard, compact = device.pdo_groups
    only_compact = set(compact.pdo_indices) - set(standard.pdo_indices)
    assert only_compact and all("Compact" in device.pdo(i).name for i in only_compact)
    # PDOs in no exclusion but assigned by default are in every group
    # (EP4374-0002: its AO outputs)
    shared = set(compact.pdo_indices) & set(standard.pdo_indices)
    assert shared == {p.index for p in device.rx_pdos if p.sm is not None}


def test_elm3704_has_192_inputs_and_26_groups(catalog: EsiCatalog) -> None:
    device = catalog.load("ELM3704-0000")
    assert len(device.tx_pdos) == 192
    assert len(device.pdo_groups) == 26
    assert device.default_group == "Oversampling 1 (24Bit)"
    default = device.group("Oversampling 1 (24Bit)")
    assert default.sm_pdos[2] == ()
    assert default.pdo_channels[0x1A90] == 4
    assert default.operation_modes == (
        "Oversampling 1 (24Bit) - DC-Synchron (input based)",
        "Oversampling 1 (24Bit) - DC-Synchron",
    )


def test_el3314_default_group_selects_inputs_only(catalog: EsiCatalog) -> None:
    device = catalog.load("EL3314")  # 2011-08 file, rev #x00120000
    assert device.revision == 0x00120000
    assert device.default_group == "Inputs only"
    inputs_only = device.group("Inputs only")
    assert inputs_only.sm_pdos == {2: (), 3: (0x1A00, 0x1A01, 0x1A02, 0x1A03)}
    cold_junction = device.group("with ColdJunction Compensation")
    assert cold_junction.sm_pdos[2] == (0x1600, 0x1601, 0x1602, 0x1603)
    # older revisions of the same file have no mapping and no Exclude
    assert catalog.load("EL3314", 0x00110000).pdo_groups == ()


@pytest.mark.parametrize("type_name", ["EL2024", "EL1014", "EL3202", "EL4134"])
def test_static_terminals_have_no_groups(catalog: EsiCatalog, type_name: str) -> None:
    device = catalog.load(type_name)
    assert device.pdo_groups == ()
    assert device.default_group is None


def test_el3356_0010_fixture_groups(catalog: EsiCatalog) -> None:
    device = catalog.load("EL3356-0010")
    assert device.default_group == "Standard (INT32)"
    assert groups(device)["Standard (REAL)"] == (0x1600, 0x1A00, 0x1A02)
    assert groups(device)["2x AnalogIn (Compact)"] == (
        0x1600,
        0x1A00,
        0x1A04,
        0x1A06,
    )
    value_types = {
        device.pdo(index).name: device.pdo(index).entries[-1].data_type
        for index in (0x1A01, 0x1A02, 0x1A03, 0x1A04)
    }
    assert value_types == {
        "RMB Value (INT32)": "DINT",
        "RMB Value (Real)": "REAL",
        "AI Standard Channel 1": "DINT",
        "AI Compact Channel 1": "DINT",
    }


def test_vendor_mapping_quirks_are_tolerated(catalog: EsiCatalog) -> None:
    # EL2014 #x00100000: "Compact Diagnostics" names #x1a01, not defined.
    el2014 = catalog.load("EL2014", 0x00100000)
    compact = el2014.group("Compact Diagnostics")
    assert compact.unknown_pdo_indices == (0x1A01,)
    assert compact.pdo_indices == (0x1600, 0x1A02)
    # EL2258: an empty <Pdo/> inside "Compatible 1 Ch."
    el2258 = catalog.load("EL2258", 0x00100000)
    assert el2258.group("Compatible 1 Ch.").sm_pdos == {2: (0x1620,), 3: ()}
    # EP3184-0002 #x00110002: one unnamed mapping is no choice; Exclude decides
    ep3184 = catalog.load("EP3184-0002", 0x00110002)
    assert [g.name for g in ep3184.pdo_groups] == ["Standard", "Compact"]
    # EL3632: a mapping holding only an empty <Name/> is ignored
    assert catalog.load("EL3632", 0x00100000).pdo_groups == ()
