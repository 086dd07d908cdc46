"""CoE SDO on each slave's port: the terminal's dictionary with ESI defaults."""

from __future__ import annotations

import struct

from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ioc.resolve import coe_object_points
from fastcs_ethercat.sim.probe import SimProbe
from fastcs_ethercat.terminals.model import CoeObject, CoeSubItem
from fastcs_ethercat.twincat.coe import CoeDictionary
from fastcs_ethercat.twincat.target import SimTarget
from tests.ads_codec import coe_index_offset
from tests.test_sim_model_support import (
    EL3104_COMPACT,
    demo_target,
    master,
    target_from_text,
)

EL3104_PORT = 1005
SDO = IndexGroup.COE_SDO


def slave(target: SimTarget, port: int = EL3104_PORT) -> SimProbe:
    return master(target).at(port)


def test_reads_esi_defaults() -> None:
    probe = slave(demo_target())
    name = probe.read(SDO, coe_index_offset(0x1008, 0), 64)
    assert name.data == b"EL3104"
    device_type = probe.read(SDO, coe_index_offset(0x1000, 0), 4)
    assert device_type.data == bytes.fromhex("89132c01")
    gain = probe.read(SDO, coe_index_offset(0x800F, 2), 2)
    assert struct.unpack("<h", gain.data)[0] == 0x4000
    count = probe.read(SDO, coe_index_offset(0x8000, 0), 1)
    assert count.data[0] >= 0x11


def test_identity_object_reports_the_slave_identity() -> None:
    target = target_from_text(
        "masters:\n- slaves: [{type: EL3104, revision: 0x00100000, serial: 77}]\n"
    )
    probe = slave(target, 1001)
    values = [
        struct.unpack("<I", probe.read(SDO, coe_index_offset(0x1018, sub), 4).data)[0]
        for sub in range(1, 5)
    ]
    assert values == [2, 0x0C203052, 0x00100000, 77]


def test_write_then_read_back() -> None:
    target = demo_target()
    probe = slave(target)
    offset = coe_index_offset(0x800F, 1)
    assert probe.write(SDO, offset, struct.pack("<h", -12)).result == 0
    assert probe.read(SDO, offset, 2).data == struct.pack("<h", -12)
    # A 3-bit enum and a 1-bit flag share a byte; each keeps its own bits.
    presentation = coe_index_offset(0x8000, 2)
    enable_scale = coe_index_offset(0x8000, 1)
    assert probe.write(SDO, presentation, b"\x05").result == 0
    assert probe.write(SDO, enable_scale, b"\x01").result == 0
    assert probe.read(SDO, presentation, 1).data == b"\x05"
    assert probe.read(SDO, enable_scale, 1).data == b"\x01"
    assert (
        probe.write(SDO, presentation, b"\x09").result
        == AdsReturnCode.DEVICE_INVALID_DATA
    )


def test_read_only_objects_refuse_writes() -> None:
    probe = slave(demo_target())
    refused = probe.write(SDO, coe_index_offset(0x1018, 2), b"\0\0\0\0")
    assert refused.result == AdsReturnCode.DEVICE_INVALID_ACCESS
    count = probe.write(SDO, coe_index_offset(0x8000, 0), b"\x01")
    assert count.result == AdsReturnCode.DEVICE_INVALID_ACCESS
    assert probe.read(SDO, coe_index_offset(0x1018, 2), 4).data == bytes.fromhex(
        "5230200c"
    )


def test_unknown_objects_and_sizes() -> None:
    probe = slave(demo_target())
    assert probe.read(SDO, coe_index_offset(0x4321, 1), 4).result == (
        AdsReturnCode.DEVICE_INVALID_OFFSET
    )
    assert probe.read(SDO, coe_index_offset(0x1018, 9), 4).result == (
        AdsReturnCode.DEVICE_INVALID_OFFSET
    )
    assert probe.write(SDO, coe_index_offset(0x800F, 1), b"\x01").result == (
        AdsReturnCode.DEVICE_INVALID_SIZE
    )
    assert probe.read(SDO, coe_index_offset(0x800F, 1), 1).result == (
        AdsReturnCode.DEVICE_INVALID_SIZE
    )
    assert probe.read(0xF020, 0, 1).result == AdsReturnCode.DEVICE_INVALID_GROUP


def test_complete_access_reads_the_whole_record() -> None:
    probe = slave(demo_target())
    whole = probe.read(SDO, coe_index_offset(0x1018, 0, complete_access=True), 64)
    assert whole.data[0] == 4
    assert whole.data[2:18] == struct.pack("<4I", 2, 0x0C203052, 0x00110000, 0)
    from_one = probe.read(SDO, coe_index_offset(0x1018, 1, complete_access=True), 64)
    assert from_one.data == whole.data[2:]


def test_mailbox_needs_preop_and_a_link() -> None:
    target = demo_target()
    probe = slave(target)
    offset = coe_index_offset(0x1018, 1)
    target.set_slave_state(EL3104_COMPACT, "INIT")
    assert probe.read(SDO, offset, 4).result == AdsReturnCode.DEVICE_NOT_READY
    target.set_slave_state(EL3104_COMPACT, "PREOP")
    assert probe.read(SDO, offset, 4).result == 0
    target.set_link_lost(EL3104_COMPACT, True)
    assert probe.read(SDO, offset, 4).result == AdsReturnCode.DEVICE_TIMEOUT


def test_slaves_without_a_dictionary() -> None:
    probe = slave(demo_target(), 1002)  # EL1014: no mailbox
    assert probe.read(SDO, coe_index_offset(0x1018, 1), 4).result == (
        AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
    )


def test_slave_port_reports_the_al_state() -> None:
    target = demo_target()
    probe = slave(target)
    assert probe.read_state().device_state == 8
    target.set_slave_state(EL3104_COMPACT, "SAFEOP")
    assert probe.read_state().device_state == 4
    assert probe.device_info().name == "EL3104"


def test_a_sub_item_without_its_own_access_has_its_objects() -> None:
    """The IOC serves such a sub-item writable when its object is rw: the
    simulator takes the write too (one rule, `CoeObject.access_of`)."""
    item = CoeSubItem(
        subindex=1, name="Limit", fastcs_name="limit", type_name="UINT", bit_size=16
    )
    settings = CoeObject(
        index=0x8000, name="Settings", fastcs_name="settings", selected=True,
        type_name="DT8000", bit_size=32, access="rw", sub_items=[item],
    )  # fmt: skip
    dictionary = CoeDictionary.from_terminal([settings])
    offset = coe_index_offset(0x8000, 1)

    assert settings.access_of(item) == "rw"
    assert dictionary.write(offset, struct.pack("<H", 300)) == 0
    assert dictionary.read(offset, 2) == (0, struct.pack("<H", 300))
    assert coe_object_points(settings)[-1].writable
