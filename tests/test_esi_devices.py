"""Full parse of every device in the real ESI files, and their quirks."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace
from pathlib import Path

import pytest

from fastcs_ethercat.esi import EsiDevice, EsiParseResult, parse_all
from fastcs_ethercat.esi.files import device_elements, parse_device_element, read_root
from tests.conftest import ESI_SUBSET as ESI


@pytest.fixture(scope="module")
def parsed() -> EsiParseResult:
    return parse_all(ESI, strict=True)


@pytest.fixture(scope="module")
def parsed_in_full(shared_esi: Path) -> EsiParseResult:
    return parse_all(shared_esi, strict=True)


def find(parsed: EsiParseResult, type_name: str, revision: int) -> EsiDevice:
    matches = [
        d for d in parsed.devices if (d.type_name, d.revision) == (type_name, revision)
    ]
    assert matches, f"{type_name} #x{revision:08x} not parsed"
    return matches[0]


def file_of(device: EsiDevice, root: Path) -> str:
    return Path(device.source).resolve().relative_to(root.resolve()).as_posix()


def test_every_device_of_every_file_parses(
    parsed_in_full: EsiParseResult, shared_esi: Path
) -> None:
    parsed = parsed_in_full
    assert parsed.warnings == ()
    assert len(parsed.devices) == 506
    counts = Counter(file_of(device, shared_esi) for device in parsed.devices)
    assert counts["Beckhoff EL1xxx.xml"] == 141
    assert counts["2011-08/Beckhoff EL3xxx.xml"] == 28
    assert counts["Beckhoff ELM37xx.xml"] == 1


def test_every_device_is_consistent(parsed_in_full: EsiParseResult) -> None:
    for device in parsed_in_full.devices:
        assert device.vendor_id == 2
        assert device.description
        pdo_indices = {pdo.index for pdo in device.pdos}
        for group in device.pdo_groups:
            assert set(group.pdo_indices) <= pdo_indices
            assert set(group.pdo_indices) == {
                i for indices in group.sm_pdos.values() for i in indices
            }
        if device.pdo_groups:
            assert sum(g.is_default for g in device.pdo_groups) <= 1
            names = [g.name for g in device.pdo_groups]
            assert len(set(names)) == len(names)
        for pdo in device.pdos:
            if pdo.channel_template is not None:
                assert pdo.channel_template.format(channel=pdo.channel) == pdo.name


def test_english_description_and_names_per_lcid(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL3104", 0x00100000)
    assert device.description == "EL3104 4Ch. Ana. Input +/-10V Diff."
    assert device.names[1031] == "EL3104 4K. Ana. Eingang  +/-10V Diff."
    assert device.group_type == "AnaIn"
    assert device.product_code == 0x0C203052


def test_latin1_file_decodes_umlauts(parsed: EsiParseResult) -> None:
    device = find(parsed, "ELM3704-0000", 0x00100000)  # encoding="ISO-8859-1"
    assert "Messbrückenauswertung" in device.names[1031]
    assert device.description.startswith("ELM3704-0000 4Ch. Ana. Input")


def test_cdata_names_and_pdos_on_sm0(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL1084", 0x00100000)  # names in CDATA, no mailbox
    assert device.description == "EL1084 4Ch. Dig. Input 24V, 3ms, negative"
    assert not device.has_mailbox
    assert {pdo.sm for pdo in device.tx_pdos} == {0}
    assert [pdo.channel for pdo in device.tx_pdos] == [1, 2, 3, 4]
    assert device.tx_pdos[0].entries[0].data_type == "BOOL"


def test_hide_types(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL1502", 0x00160000)
    assert [h.revision for h in device.hide_types] == [
        0x00100000, 0x00110000, 0x00120000, 0x00130000, 0x00140000, 0x00150000,
    ]  # fmt: skip
    coupler = find(parsed, "EK1100", 0x00000000)
    hidden = {(h.product_code, h.revision, h.name) for h in coupler.hide_types}
    assert (0x044C2C52, 0x27070000, "EK1100-0000-9991") in hidden


def test_padding_entries(parsed: EsiParseResult) -> None:
    pdo = find(parsed, "EL3104", 0x00110000).pdo(0x1A00)
    gaps = [entry for entry in pdo.entries if entry.is_padding]
    assert [(g.bit_len, g.subindex, g.data_type) for g in gaps] == [
        (1, 0, None),
        (5, 0, None),
    ]
    value = pdo.entries[-1]
    assert (value.index, value.subindex, value.bit_len, value.name) == (
        0x6000,
        17,
        16,
        "Value",
    )
    assert (value.data_type, value.dscale) == ("INT", "+/-10")
    assert sum(entry.bit_len for entry in pdo.entries) == 32


def test_uppercase_and_short_hex(parsed: EsiParseResult) -> None:
    el4134 = find(parsed, "EL4134", 0x03FA0000)  # spelt #x03fa0000
    assert el4134.revision == 0x03FA0000
    el3702 = find(parsed, "EL3702", 0x00020000)
    next_sync = el3702.pdo(0x1B10)
    assert next_sync.virtual
    assert next_sync.entries[0].subindex == 0x98  # SubIndex #x98


def test_duplicate_pdo_index_is_kept(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL2252", 0x00110000)  # #x1602 defined twice
    names = [pdo.name for pdo in device.rx_pdos if pdo.index == 0x1602]
    assert names == ["DC Sync Activate", "Reserved"]


def test_data_types_enums_records_and_arrays(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL3104", 0x00110000)
    presentation = device.data_types["DT0800EN03"]
    assert presentation.base_type == "USINT"
    assert presentation.bit_size == 3
    assert [(item.value, item.text) for item in presentation.enum_items] == [
        (0, "Signed"),
        (1, "Unsigned"),
        (2, "Absolute MSB sign"),
    ]
    array = device.data_types["ARRAY [0..1] OF BYTE"]
    assert (array.array_lbound, array.array_elements, array.base_type) == (
        0,
        2,
        "BYTE",
    )
    record = device.data_types["DT8000"]
    assert record.sub_items[1].name == "Enable user scale"
    assert record.sub_items[1].access == "rw"


def test_coe_objects_with_defaults_and_enum_texts(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL3104", 0x00110000)
    assert device.has_coe
    name = device.coe_objects[0x1008]
    assert (name.type_name, name.access, name.default_data) == (
        "STRING(6)",
        "ro",
        "454c33313034",
    )
    settings = device.coe_objects[0x8000]
    by_name = {item.name: item for item in settings.sub_items}
    presentation = by_name["Presentation"]
    assert (presentation.subindex, presentation.access) == (2, "rw")
    assert [item.text for item in presentation.enum_items] == [
        "Signed",
        "Unsigned",
        "Absolute MSB sign",
    ]
    assert by_name["Enable vendor calibration"].default_data == "01"
    gain = by_name["User scale gain"]
    assert (gain.default_value, gain.min_value, gain.max_value) == (
        "#x10000",
        "#xfff80000",
        "#x7ffff",
    )


def test_coe_array_members_expand_to_subindices(parsed: EsiParseResult) -> None:
    device = find(parsed, "EL3104", 0x00110000)
    restore = device.coe_objects[0x1011]  # DT1011: SubIndex 000 + Elements[1]
    assert [
        (s.subindex, s.name, s.type_name, s.bit_size) for s in restore.sub_items
    ] == [
        (0, "SubIndex 000", "USINT", 8),
        (1, "SubIndex 001", "UDINT", 32),
    ]
    assert restore.sub_items[1].default_data == "00000000"


def test_oversampling_templates_el3702_el4732(parsed: EsiParseResult) -> None:
    el3702 = find(parsed, "EL3702", 0x00020000)
    oversampling = el3702.oversampling
    assert oversampling is not None
    assert oversampling.origin == "pdo_attributes"
    assert oversampling.pdo_indices == (0x1A00, 0x1A80)
    assert oversampling.default_factor == 10
    assert (oversampling.min_factor, oversampling.max_factor) == (1, 100)
    assert oversampling.index_increment == 16
    assert 100 in oversampling.factors and 1 in oversampling.factors
    assert el3702.pdo(0x1A00).channel_template == "Ch{channel} Sample"
    el4732 = find(parsed, "EL4732", 0x00040000)
    assert el4732.oversampling is not None
    assert el4732.oversampling.pdo_indices == (0x1600, 0x1700)
    assert el4732.pdo(0x1600).direction == "rx"


def test_oversampling_by_groups_elm3704(parsed: EsiParseResult) -> None:
    device = find(parsed, "ELM3704-0000", 0x00100000)
    oversampling = device.oversampling
    assert oversampling is not None
    assert oversampling.origin == "pdo_groups"
    assert oversampling.factors == (
        1,
        2,
        4,
        5,
        8,
        10,
        16,
        20,
        25,
        32,
        40,
        50,
        64,
        80,
        100,
    )
    assert oversampling.default_factor == 1
    assert oversampling.group_factors["Oversampling 10 (REAL32)"] == 10
    assert "Ch 1+2 Ovs 5 - Ch 3+4 Ovs 10 (24Bit)" not in oversampling.group_factors
    samples = device.pdo(0x1A06)
    assert samples.name == "PAI Samples 10 Channel 1"
    assert samples.channel_template == "PAI Samples 10 Channel {channel}"
    assert len(samples.entries) == 10 and 0x1A06 in oversampling.pdo_indices


def test_static_terminals_have_no_oversampling(parsed: EsiParseResult) -> None:
    for type_name, revision in (("EL3104", 0x00110000), ("EL2024", 0x00130000)):
        assert find(parsed, type_name, revision).oversampling is None


def test_coupler_without_pdos(parsed: EsiParseResult) -> None:
    device = find(parsed, "EK1100", 0x00120000)
    assert device.pdos == ()
    assert device.coe_objects == {}
    assert device.pdo_groups == ()


def test_shared_elements_parse_like_fresh_ones(parsed: EsiParseResult) -> None:
    # parse_all reuses identical PDOs/types/objects within a document; the
    # result must equal a device parsed on its own.
    source = ESI / "Beckhoff EL31xx.xml"
    root = read_root(source.read_bytes(), str(source))
    memoised = {
        (d.type_name, d.revision): d
        for d in parsed.devices
        if Path(d.source).name == source.name
    }
    for position, element in enumerate(device_elements(root)):
        alone = parse_device_element(element, position, vendor_id=2, source=str(source))
        shared = memoised[(alone.type_name, alone.revision)]
        assert alone == replace(shared, source=alone.source)
