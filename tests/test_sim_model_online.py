"""Online change: the symbol version moves, offsets move, old handles fail,
and dynamic PDOs can change with it."""

from __future__ import annotations

import struct

import pytest

from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ads.symbols import AdsSymbolEntry, decode_symbol_table
from fastcs_ethercat.sim.probe import SimProbe
from tests.test_sim_model_support import (
    EL1502_TWO_COUNTERS,
    EL2024,
    EL3104_COMPACT,
    EL4134,
    demo_target,
    device,
    handle_of,
    info_by_name,
)


def version(probe: SimProbe) -> int:
    return probe.read(IndexGroup.SYM_VERSION, 0, 1).data[0]


def entry(probe: SimProbe, name: str) -> AdsSymbolEntry:
    return AdsSymbolEntry.decode(info_by_name(probe, name).data)


def test_online_change_bumps_the_version_and_moves_offsets() -> None:
    target = demo_target()
    probe = device(target)
    name = f"{EL4134}.AO Output Channel 1"
    before = entry(probe, name)
    first = version(probe)
    target.online_change()
    after = entry(probe, name)
    assert version(probe) == (first % 255) + 1
    assert after.index_offset != before.index_offset
    assert (after.index_group, after.type_name) == (
        before.index_group,
        before.type_name,
    )


def test_old_handles_fail_new_ones_work() -> None:
    target = demo_target()
    probe = device(target)
    name = f"{EL4134}.AO Output Channel 4"
    target.set_symbol_value(name, 2024)
    old = handle_of(probe, name)
    target.online_change()
    stale = probe.read(IndexGroup.SYM_VALUE_BY_HANDLE, old, 2)
    assert stale.result == AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID
    write = probe.write(IndexGroup.SYM_VALUE_BY_HANDLE, old, b"\0\0")
    assert write.result == AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID
    fresh = handle_of(probe, name)
    # Values of surviving symbols are kept across the change.
    assert probe.read(IndexGroup.SYM_VALUE_BY_HANDLE, fresh, 2).data == struct.pack(
        "<h", 2024
    )
    assert (
        probe.write(IndexGroup.SYM_RELEASE_HANDLE, 0, struct.pack("<I", old)).result
        == 0
    )


def test_a_handle_stays_invalid_when_the_symbol_version_wraps() -> None:
    """The version is one byte and comes back after 255 changes; a handle
    taken before them must not come back to life with it."""
    target = demo_target()
    probe = device(target)
    name = f"{EL4134}.AO Output Channel 4"
    old = handle_of(probe, name)
    first = version(probe)
    target.online_change()
    for each in target.devices:  # as after 255 changes: the byte wrapped
        each.version = first
    assert version(probe) == first
    stale = probe.write(IndexGroup.SYM_VALUE_BY_HANDLE, old, b"\1\0")
    assert stale.result == AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID


def test_upload_reflects_the_new_offsets() -> None:
    target = demo_target()
    probe = device(target)

    def offsets() -> dict[str, int]:
        table = probe.read(IndexGroup.SYM_UPLOAD, 0, 1 << 20).data
        return {e.name: e.index_offset for e in decode_symbol_table(table)}

    before = offsets()
    target.online_change()
    after = offsets()
    assert before.keys() == after.keys()
    name = f"{EL4134}.AO Output Channel 1"
    assert after[name] == entry(probe, name).index_offset != before[name]


def test_online_change_can_switch_pdo_groups() -> None:
    target = demo_target()
    probe = device(target)
    assert info_by_name(probe, f"{EL3104_COMPACT}.AI Compact Channel 1").result == 0
    target.online_change(
        {EL3104_COMPACT: "Standard", EL1502_TWO_COUNTERS: "1Ch. +/- Counter"}
    )
    compact = info_by_name(probe, f"{EL3104_COMPACT}.AI Compact Channel 1")
    assert compact.result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    standard = entry(probe, f"{EL3104_COMPACT}.AI Standard Channel 1")
    assert standard.type_name == "AI Standard Channel 1_TYPE"
    assert info_by_name(probe, f"{EL1502_TWO_COUNTERS}.CNT Inputs").result == 0
    assert info_by_name(
        probe, f"{EL1502_TWO_COUNTERS}.CNT Inputs Channel 1"
    ).result == (AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND)
    with pytest.raises(KeyError):
        target.online_change({"Term 99 (EL9999)": "Standard"})
    with pytest.raises(ValueError):
        target.online_change({EL3104_COMPACT: "Fancy"})


def test_describe_shows_the_symbol_version() -> None:
    target = demo_target()
    first = target.describe()["masters"][0]["symbol_version"]
    target.online_change()
    assert target.describe()["masters"][0]["symbol_version"] == first + 1


def test_online_change_can_take_a_slave_off_the_bus() -> None:
    target = demo_target()
    probe = device(target)
    name = f"{EL4134}.AO Output Channel 4"
    target.set_symbol_value(name, 2024)
    count = len(target.devices[0].ethercat.slaves)
    assert info_by_name(probe, f"{EL2024}.Channel 1").result == 0

    target.online_change(removed=[EL2024])

    slaves = target.devices[0].ethercat.slaves
    assert len(slaves) == count - 1
    assert EL2024 not in [runtime.slave.name for runtime in slaves]
    assert [runtime.slave.position for runtime in slaves] == list(range(count - 1))
    gone = info_by_name(probe, f"{EL2024}.Channel 1")
    assert gone.result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    fresh = handle_of(probe, name)
    assert probe.read(IndexGroup.SYM_VALUE_BY_HANDLE, fresh, 2).data == struct.pack(
        "<h", 2024
    )
    with pytest.raises(KeyError):
        target.online_change(removed=["Term 99 (EL9999)"])
