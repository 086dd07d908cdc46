"""The device port's symbol table: upload, names and types as TwinCAT makes
them, dynamic PDOs, handles, value and info by name.

Uploads are decoded twice: with our codec and with pyads' own parsing
(`SAdsSymbolEntry`, `Connection.get_all_symbols`, `dict_from_bytes`), so a
layout mistake shared by our encoder and decoder still shows.
"""

from __future__ import annotations

import ctypes
import struct
from typing import Any

import pyads
import pyads.connection
import pytest
from pyads.pyads_ex import ADSError, get_value_from_ctype_data, type_is_string
from pyads.structs import SAdsSymbolEntry, SAdsSymbolUploadInfo

from fastcs_ethercat.ads.constants import (
    AdsDataType,
    AdsReturnCode,
    DataTypeFlag,
    IndexGroup,
)
from fastcs_ethercat.ads.datatypes import (
    AdsDataTypeEntry,
    decode_data_type_table,
    walk_members,
)
from fastcs_ethercat.ads.symbols import (
    AdsSymbolEntry,
    SymbolUploadInfo,
    SymbolUploadInfo2,
    decode_symbol_table,
)
from fastcs_ethercat.sim.probe import SimProbe
from fastcs_ethercat.twincat.target import SimTarget
from tests.test_sim_model_support import (
    EL1014,
    EL1502_TWO_COUNTERS,
    EL2024,
    EL3104_COMPACT,
    EL3104_STANDARD,
    EL3702,
    demo_target,
    device,
    handle_of,
    info_by_name,
    target_from_text,
    value_by_name,
)


@pytest.fixture(scope="module")
def target() -> SimTarget:
    return demo_target()


@pytest.fixture(scope="module")
def probe(target: SimTarget) -> SimProbe:
    return device(target)


@pytest.fixture(scope="module")
def symbols(probe: SimProbe) -> dict[str, AdsSymbolEntry]:
    info = SymbolUploadInfo2.decode(
        probe.read(IndexGroup.SYM_UPLOAD_INFO_2, 0, 24).data
    )
    table = probe.read(IndexGroup.SYM_UPLOAD, 0, info.symbol_table_size).data
    entries = decode_symbol_table(table, info.symbol_count)
    return {entry.name: entry for entry in entries}


@pytest.fixture(scope="module")
def data_types(probe: SimProbe) -> dict[str, AdsDataTypeEntry]:
    info = SymbolUploadInfo2.decode(
        probe.read(IndexGroup.SYM_UPLOAD_INFO_2, 0, 24).data
    )
    table = probe.read(IndexGroup.SYM_DT_UPLOAD, 0, info.data_type_table_size).data
    entries = decode_data_type_table(table, info.data_type_count)
    return {entry.name: entry for entry in entries}


def pyads_entry(raw: bytes) -> SAdsSymbolEntry:
    """A symbol entry as pyads' ctypes structure reads it."""
    size = ctypes.sizeof(SAdsSymbolEntry)
    return SAdsSymbolEntry.from_buffer_copy(raw[:size].ljust(size, b"\0"))


# -- the upload ----------------------------------------------------------------


def test_upload_info_blocks_agree_with_the_table(probe: SimProbe) -> None:
    info2 = SymbolUploadInfo2.decode(
        probe.read(IndexGroup.SYM_UPLOAD_INFO_2, 0, 1024).data
    )
    info = SymbolUploadInfo.decode(probe.read(IndexGroup.SYM_UPLOAD_INFO, 0, 8).data)
    pyads_info = SAdsSymbolUploadInfo.from_buffer_copy(
        probe.read(IndexGroup.SYM_UPLOAD_INFO, 0, 8).data
    )
    assert (info.symbol_count, info.symbol_table_size) == (
        info2.symbol_count,
        info2.symbol_table_size,
    )
    assert (pyads_info.nSymbols, pyads_info.nSymSize) == (
        info.symbol_count,
        info.symbol_table_size,
    )
    table = probe.read(IndexGroup.SYM_UPLOAD, 0, info2.symbol_table_size).data
    assert len(table) == info2.symbol_table_size
    # A read longer than the table gets the bytes there are; a shorter one fails.
    assert probe.read(IndexGroup.SYM_UPLOAD, 0, len(table) + 100).data == table
    short = probe.read(IndexGroup.SYM_UPLOAD, 0, len(table) - 1)
    assert short.result == AdsReturnCode.DEVICE_INVALID_SIZE


def test_pyads_get_all_symbols_reads_the_upload(
    probe: SimProbe, symbols: dict[str, AdsSymbolEntry], monkeypatch: pytest.MonkeyPatch
) -> None:
    """pyads' own walk over the table (its transport replaced by the probe)."""

    def read(
        port: int,
        address: Any,
        group: int,
        offset: int,
        data_type: Any,
        return_ctypes: bool = False,
        check_length: bool = True,
    ) -> Any:
        buffer = (ctypes.c_char * 1024)() if type_is_string(data_type) else data_type()
        answer = probe.read(group, offset, ctypes.sizeof(buffer))
        if answer.result:
            raise ADSError(answer.result)
        ctypes.memmove(buffer, answer.data, len(answer.data))
        return buffer if return_ctypes else get_value_from_ctype_data(buffer, data_type)

    monkeypatch.setattr(pyads.connection, "adsSyncReadReqEx2", read)
    connection = pyads.Connection("127.0.0.1.1.1", 27905)
    connection._port = 1  # "open", so get_all_symbols uses its read
    found = connection.get_all_symbols()
    assert [s.name for s in found] == sorted(symbols)
    by_name = {s.name: s for s in found}
    name = f"{EL3104_COMPACT}.AI Compact Channel 1"
    compact = by_name[name]
    assert compact.symbol_type == "INT"
    assert compact.plc_type is pyads.PLCTYPE_INT
    assert compact.index_group == symbols[name].index_group
    assert compact.index_offset == symbols[name].index_offset


def test_every_entry_reads_the_same_with_pyads_structures(
    probe: SimProbe, symbols: dict[str, AdsSymbolEntry]
) -> None:
    for name, entry in symbols.items():
        raw = info_by_name(probe, name).data
        theirs = pyads_entry(raw)
        assert AdsSymbolEntry.decode(raw) == entry
        assert theirs.entryLength == len(raw)
        assert (theirs.name, theirs.symbol_type, theirs.comment) == (
            entry.name,
            entry.type_name,
            entry.comment,
        )
        assert (theirs.iGroup, theirs.iOffs, theirs.size, theirs.dataType) == (
            entry.index_group,
            entry.index_offset,
            entry.size,
            int(entry.data_type),
        )


def test_upload_is_sorted_by_name(symbols: dict[str, AdsSymbolEntry]) -> None:
    names = list(symbols)
    assert names == sorted(names)


# -- names and types as TwinCAT makes them (facts section 7) ---------------------


def test_compact_pdo_is_a_plain_int(symbols: dict[str, AdsSymbolEntry]) -> None:
    for channel in range(1, 5):
        entry = symbols[f"{EL3104_COMPACT}.AI Compact Channel {channel}"]
        assert (entry.data_type, entry.type_name, entry.size) == (
            AdsDataType.INT16,
            "INT",
            2,
        )
        assert entry.index_group == IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES  # 0xF030
    assert not any(name.startswith(f"{EL3104_COMPACT}.AI Standard") for name in symbols)


def test_standard_pdo_is_a_structure_with_status_bits_and_value_at_2(
    symbols: dict[str, AdsSymbolEntry], data_types: dict[str, AdsDataTypeEntry]
) -> None:
    entry = symbols[f"{EL3104_STANDARD}.AI Standard Channel 1"]
    assert (entry.data_type, entry.type_name, entry.size) == (
        AdsDataType.BIGTYPE,
        "AI Standard Channel 1_TYPE",
        4,
    )
    # Every channel shares the first channel's type.
    for channel in range(2, 5):
        other = symbols[f"{EL3104_STANDARD}.AI Standard Channel {channel}"]
        assert other.type_name == "AI Standard Channel 1_TYPE"
    layout = data_types["AI Standard Channel 1_TYPE"]
    members = {item.name: item for item in layout.sub_items}
    assert list(members) == ["Status", "Value"]
    assert (members["Value"].type_name, members["Value"].offset) == ("INT", 2)
    status = data_types[members["Status"].type_name]
    bits = {item.name: item for item in status.sub_items}
    assert {"Underrange", "Overrange", "Limit 1", "Limit 2", "Error"} <= set(bits)
    assert all(item.flags & DataTypeFlag.BIT_VALUES for item in bits.values())
    assert (bits["Overrange"].offset, bits["Limit 1"].size) == (1, 2)


def test_codec_flattens_the_uploaded_layouts(
    data_types: dict[str, AdsDataTypeEntry],
) -> None:
    """The IOC's view: every leaf of a structure with its bit or byte offset."""
    leaves = {
        m.path: m
        for m in walk_members(data_types["AI Standard Channel 1_TYPE"], data_types)
    }
    assert (leaves["Value"].offset, leaves["Value"].bit_size) == (2, 0)
    error = leaves["Status.Error"]
    assert (error.offset, error.size, error.bit_offset, error.bit_size) == (0, 2, 6, 1)
    assert leaves["Status.Limit 2"].bit_offset == 4


def test_pyads_reads_the_standard_structure_by_its_layout(target: SimTarget) -> None:
    name = f"{EL3104_STANDARD}.AI Standard Channel 1"
    target.set_symbol_value(name, {"Value": -1234, "Status": {"Overrange": True}})
    raw = value_by_name(device(target), name, 4).data
    structure = (("Status", pyads.PLCTYPE_UINT, 1), ("Value", pyads.PLCTYPE_INT, 1))
    assert pyads.ads.size_of_structure(structure) == 4
    assert pyads.ads.dict_from_bytes(bytearray(raw), structure) == {
        "Status": 0b10,
        "Value": -1234,
    }
    target.clear_faults()


def test_digital_channels_are_bits_in_the_bit_images(
    symbols: dict[str, AdsSymbolEntry],
) -> None:
    inputs = [symbols[f"{EL1014}.Channel {n}"] for n in range(1, 5)]
    outputs = [symbols[f"{EL2024}.Channel {n}"] for n in range(1, 5)]
    for entry in inputs + outputs:
        assert (entry.data_type, entry.type_name, entry.size) == (
            AdsDataType.BIT,
            "BIT",
            1,
        )
    assert {e.index_group for e in inputs} == {IndexGroup.IO_IMAGE_RW_OUTPUT_BITS}
    assert {e.index_group for e in outputs} == {IndexGroup.IO_IMAGE_RW_INPUT_BITS}
    offsets = [e.index_offset for e in inputs]
    assert offsets == list(range(offsets[0], offsets[0] + 4))  # packed bit by bit


def test_runtime_symbols_of_terminals_and_master(
    symbols: dict[str, AdsSymbolEntry], data_types: dict[str, AdsDataTypeEntry]
) -> None:
    for terminal in (EL1014, EL3104_COMPACT, EL1502_TWO_COUNTERS):
        for item in ("WcState", "InputToggle"):
            entry = symbols[f"{terminal}.WcState.{item}"]
            assert (entry.data_type, entry.index_group) == (
                AdsDataType.BIT,
                IndexGroup.IO_IMAGE_RW_OUTPUT_BITS,
            )
    # Outputs-only terminals have a WcState but no InputToggle; couplers neither.
    assert f"{EL2024}.WcState.WcState" in symbols
    assert f"{EL2024}.WcState.InputToggle" not in symbols
    assert not any(name.startswith("Term 1 (EK1100).") for name in symbols)
    # Terminals in the same datagram share one WcState bit.
    assert (
        symbols[f"{EL1014}.WcState.WcState"].index_offset
        == symbols[f"{EL3104_COMPACT}.WcState.WcState"].index_offset
    )
    inputs = symbols["Device 1 (EtherCAT).Inputs"]
    assert (inputs.type_name, inputs.index_group) == ("Inputs_TYPE", 0xF030)
    members = {m.name: m.offset for m in data_types["Inputs_TYPE"].sub_items}
    assert members == {
        "Frm0State": 0,
        "Frm0WcState": 2,
        "Frm0InputToggle": 4,
        "SlaveCount": 10,
        "DevState": 14,
    }
    outputs = symbols["Device 1 (EtherCAT).Outputs"]
    assert (outputs.type_name, outputs.index_group) == ("Outputs_TYPE", 0xF020)
    assert "SyncUnits._default_._unreferenced_.WcState.WcState" in symbols
    # InfoData is a TwinCAT option, off by default (none in real rack dumps).
    assert not any(".InfoData." in name for name in symbols)


def test_info_data_when_the_master_asks_for_it() -> None:
    target = target_from_text(
        "masters:\n- info_data: true\n  slaves: [{type: EK1100}, {type: EL3104}]\n"
    )
    assert target.get_symbol_value("Term 2 (EL3104).InfoData.State") == 8
    address = target.get_symbol_value("Term 2 (EL3104).InfoData.AdsAddr")
    assert address == {"netId": [127, 0, 0, 1, 2, 1], "port": 1002}
    target.set_slave_state(1002, "SAFEOP")
    assert target.get_symbol_value("Term 2 (EL3104).InfoData.State") == 4


def test_oversampling_gives_an_array_of_samples(
    symbols: dict[str, AdsSymbolEntry], data_types: dict[str, AdsDataTypeEntry]
) -> None:
    entry = symbols[f"{EL3702}.Ch1 Sample 0"]
    assert (entry.data_type, entry.type_name, entry.size) == (
        AdsDataType.BIGTYPE,
        "Ch1 Sample 0_TYPE_ARR",
        20,
    )
    array = data_types["Ch1 Sample 0_TYPE_ARR"]
    assert array.type_name == "INT"
    assert [(d.lower_bound, d.element_count) for d in array.array_dimensions] == [
        (0, 10)
    ]


def test_same_name_different_layout_is_numbered() -> None:
    target = target_from_text(
        """
masters:
- slaves:
  - type: EL1502
    pdo_group: 2Ch. Counter
  - type: EL1502
"""
    )
    names = [t.name for t in target.devices[0].layout.types]
    assert "CNT Inputs Channel 1_TYPE" in names
    assert "CNT Inputs_TYPE" in names
    assert len(names) == len(set(names))


# -- dynamic PDOs -----------------------------------------------------------------


def test_active_pdo_group_decides_which_symbols_exist(
    symbols: dict[str, AdsSymbolEntry],
) -> None:
    el1502 = [n for n in symbols if n.startswith(f"{EL1502_TWO_COUNTERS}.CNT")]
    assert sorted(el1502) == [
        f"{EL1502_TWO_COUNTERS}.CNT Inputs Channel 1",
        f"{EL1502_TWO_COUNTERS}.CNT Inputs Channel 2",
        f"{EL1502_TWO_COUNTERS}.CNT Outputs Channel 1",
        f"{EL1502_TWO_COUNTERS}.CNT Outputs Channel 2",
    ]
    default = target_from_text("masters:\n- slaves: [{type: EL1502}]\n")
    names = {s.name for s in default.devices[0].table.symbols}
    assert "Term 1 (EL1502).CNT Inputs" in names
    assert "Term 1 (EL1502).CNT Inputs Channel 1" not in names


def test_pdos_outside_the_selected_group_are_not_assigned() -> None:
    target = target_from_text("masters:\n- slaves: [{type: ELM3704-0000}]\n")
    names = {
        s.name.removeprefix("Term 1 (ELM3704-0000).")
        for s in target.devices[0].table.symbols
    }
    assert "PAI Samples 1 Channel 1" in names
    assert "PAI Samples 2 Channel 1" not in names  # no mapping assigns it
    assert "PAI Control Channel 1" not in names  # the mapping leaves SM2 empty


# -- by name and by handle -----------------------------------------------------------


def test_info_by_name_for_members_and_aliases(probe: SimProbe) -> None:
    member = AdsSymbolEntry.decode(
        info_by_name(probe, f"{EL3104_STANDARD}.AI Standard Channel 2.Value").data
    )
    parent = AdsSymbolEntry.decode(
        info_by_name(probe, f"{EL3104_STANDARD}.AI Standard Channel 2").data
    )
    assert (member.type_name, member.size, member.index_group) == ("INT", 2, 0xF030)
    assert member.index_offset == parent.index_offset + 2
    bit = AdsSymbolEntry.decode(
        info_by_name(
            probe, f"{EL3104_STANDARD}.AI Standard Channel 2.Status.Error"
        ).data
    )
    assert (bit.type_name, bit.index_group) == ("BIT", 0xF031)
    assert bit.index_offset == 8 * parent.index_offset + 6
    # The entry of a one-entry PDO is reachable as TwinCAT's tree shows it.
    alias = AdsSymbolEntry.decode(info_by_name(probe, f"{EL1014}.Channel 1.Input").data)
    channel = AdsSymbolEntry.decode(info_by_name(probe, f"{EL1014}.Channel 1").data)
    assert (alias.index_group, alias.index_offset) == (
        channel.index_group,
        channel.index_offset,
    )
    element = AdsSymbolEntry.decode(
        info_by_name(probe, f"{EL3702}.Ch1 Sample 0[3]").data
    )
    whole = AdsSymbolEntry.decode(info_by_name(probe, f"{EL3702}.Ch1 Sample 0").data)
    assert (element.type_name, element.index_offset) == ("INT", whole.index_offset + 6)


def test_names_are_case_insensitive(probe: SimProbe) -> None:
    upper = info_by_name(probe, f"{EL3104_COMPACT}.AI COMPACT CHANNEL 3".upper())
    assert upper.result == 0


@pytest.mark.parametrize(
    "name",
    [
        "nothing",
        f"{EL3104_COMPACT}.AI Standard Channel 1",  # not in the active group
        f"{EL3104_STANDARD}.AI Standard Channel 1.Nope",
        f"{EL3702}.Ch1 Sample 0[10]",
        "",
    ],
)
def test_unknown_names_answer_symbol_not_found(probe: SimProbe, name: str) -> None:
    assert info_by_name(probe, name).result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    assert value_by_name(probe, name, 8).result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    handle = probe.read_write(
        IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, name.encode() + b"\0"
    )
    assert handle.result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND


def test_short_reads_of_a_value_give_its_first_bytes(probe: SimProbe) -> None:
    """A value read shorter than its symbol gets the first bytes (facts 9);
    a symbol entry or a handle does not fit a short buffer (0x705)."""
    name = f"{EL3104_STANDARD}.AI Standard Channel 1"
    whole = value_by_name(probe, name, 4).data
    assert value_by_name(probe, name, 2).data == whole[:2]
    assert info_by_name(probe, name, 10).result == AdsReturnCode.DEVICE_INVALID_SIZE
    answer = probe.read_write(
        IndexGroup.SYM_HANDLE_BY_NAME, 0, 2, name.encode() + b"\0"
    )
    assert answer.result == AdsReturnCode.DEVICE_INVALID_SIZE


def test_handles_read_write_and_release() -> None:
    target = demo_target()
    probe = device(target)
    name = f"{EL3104_COMPACT}.AI Compact Channel 2"
    handle = handle_of(probe, name)
    target.set_symbol_value(name, 1234)
    assert probe.read(IndexGroup.SYM_VALUE_BY_HANDLE, handle, 2).data == struct.pack(
        "<h", 1234
    )
    assert value_by_name(probe, name, 2).data == struct.pack("<h", 1234)
    output = handle_of(probe, "Term 15 (EL4134).AO Output Channel 3")
    write = probe.write(IndexGroup.SYM_VALUE_BY_HANDLE, output, struct.pack("<h", -500))
    assert write.result == 0
    assert target.get_symbol_value("Term 15 (EL4134).AO Output Channel 3") == -500
    wrong = probe.write(IndexGroup.SYM_VALUE_BY_HANDLE, output, b"\0")
    assert wrong.result == AdsReturnCode.DEVICE_INVALID_SIZE
    release = probe.write(IndexGroup.SYM_RELEASE_HANDLE, 0, struct.pack("<I", handle))
    assert release.result == 0
    gone = probe.read(IndexGroup.SYM_VALUE_BY_HANDLE, handle, 2)
    assert gone.result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    again = probe.write(IndexGroup.SYM_RELEASE_HANDLE, 0, struct.pack("<I", handle))
    assert again.result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND


def test_bit_symbols_read_and_write_one_byte() -> None:
    target = demo_target()
    probe = device(target)
    handle = handle_of(probe, f"{EL2024}.Channel 3")
    assert probe.write(IndexGroup.SYM_VALUE_BY_HANDLE, handle, b"\x01").result == 0
    assert target.get_symbol_value(f"{EL2024}.Channel 3") is True
    assert probe.read(IndexGroup.SYM_VALUE_BY_HANDLE, handle, 1).data == b"\x01"
    assert target.get_symbol_value(f"{EL2024}.Channel 2") is False


def test_symbol_version_is_one_byte(probe: SimProbe) -> None:
    answer = probe.read(IndexGroup.SYM_VERSION, 0, 1)
    assert answer.result == 0 and len(answer.data) == 1
    assert probe.write(IndexGroup.SYM_VERSION, 0, b"\x07").result == (
        AdsReturnCode.DEVICE_INVALID_ACCESS
    )


def test_unknown_groups_on_the_device_port(probe: SimProbe) -> None:
    assert probe.read(0x1234, 0, 4).result == AdsReturnCode.DEVICE_INVALID_GROUP
    assert probe.write(0x1234, 0, b"\0").result == AdsReturnCode.DEVICE_INVALID_GROUP
    assert (
        probe.read_write(0x1234, 0, 4, b"").result == AdsReturnCode.DEVICE_INVALID_GROUP
    )
    # A known group through a service it does not offer.
    assert probe.read(IndexGroup.SYM_HANDLE_BY_NAME, 0, 4).result == (
        AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
    )
    assert probe.read_write(IndexGroup.SYM_VERSION, 0, 1, b"").result == (
        AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
    )


def test_the_masters_symbols_carry_the_device_name_as_terminals_carry_theirs() -> None:
    """On the device port the master's own symbols are named after the device
    (`Device 1 (EtherCAT).Inputs.Frm0State`) as a terminal's are after the
    terminal (`Term 5 (EL3104).AI Compact Channel 1`): fastcs-catio's notes
    of real hardware list them so, and its client prefixes every node's
    relative name (`Inputs.Frm0State`, `Channel 1`) with that node's own name.
    The bare relative name is no symbol."""
    probe = device(demo_target())
    full = info_by_name(probe, "Device 1 (EtherCAT).Inputs.Frm0State")
    bare = info_by_name(probe, "Inputs.Frm0State")

    assert full.result == AdsReturnCode.NO_ERROR
    assert AdsSymbolEntry.decode(full.data).size == 2
    assert bare.result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
