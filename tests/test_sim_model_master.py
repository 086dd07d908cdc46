"""I/O server, EtherCAT master and routing, through encoded packets."""

from __future__ import annotations

from dataclasses import replace

import pytest

from fastcs_ethercat.ads.commands import ReadRequest
from fastcs_ethercat.ads.constants import (
    RESPONSE_FLAGS,
    AdsReturnCode,
    AdsState,
    EtherCatMasterGroup,
    IndexGroup,
)
from fastcs_ethercat.ads.ethercat import (
    AlState,
    CrcCounters,
    FrameCounters,
    LinkState,
    SlaveIdentity,
    SlaveState,
    decode_device_count,
    decode_device_ids,
    decode_device_name,
    decode_device_netid,
    decode_device_type,
    decode_master_state,
    decode_slave_addresses,
    decode_slave_count,
    decode_slave_states,
)
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.sim.probe import ProbeError
from fastcs_ethercat.twincat.target import SimTarget
from tests.test_sim_model_support import (
    DEVICE_NET_ID,
    EL1014,
    EL3104_COMPACT,
    demo_target,
    device,
    master,
    target_from_text,
)

SLAVES = 24


@pytest.fixture(scope="module")
def target() -> SimTarget:
    """A demo target nobody changes (tests that change state build their own)."""
    return demo_target()


def test_responses_swap_addresses_and_keep_the_invoke_id(target: SimTarget) -> None:
    probe = device(target).at(300)
    sent, answer = probe.exchange(ReadRequest(IndexGroup.IO_SERVER_DEVICES, 2, 4))
    assert answer.target == sent.source
    assert answer.source == sent.target
    assert answer.invoke_id == sent.invoke_id
    assert answer.command == sent.command
    assert answer.state_flags == RESPONSE_FLAGS == 0x0005
    assert answer.error_code == 0


def test_unknown_ports_answer_ams_error_6(target: SimTarget) -> None:
    for probe in (device(target).at(851), device(target, 2), master(target).at(999)):
        _, answer = probe.exchange(ReadRequest(0xF020, 0, 1))
        assert answer.error_code == AdsReturnCode.TARGET_PORT_NOT_FOUND
        assert answer.payload == b""


def test_foreign_net_ids_answer_ams_error_7(target: SimTarget) -> None:
    probe = device(target).at(300, AmsNetId.parse("1.2.3.4.5.6"))
    _, answer = probe.exchange(ReadRequest(0x5000, 2, 4))
    assert answer.error_code == AdsReturnCode.TARGET_MACHINE_NOT_FOUND


def test_io_server_lists_the_devices(target: SimTarget) -> None:
    io = device(target).at(300)
    info = io.device_info()
    assert (info.name, info.major, info.minor, info.build) == ("I/O Server", 3, 1, 2103)
    assert decode_device_count(io.read(0x5000, 2, 4).data) == 1
    assert decode_device_ids(io.read(0x5000, 1, 64).data) == (1,)
    assert decode_device_name(io.read(0x5001, 1, 256).data) == "Device 1 (EtherCAT)"
    assert decode_device_netid(io.read(0x5001, 5, 6).data) == DEVICE_NET_ID
    assert decode_device_type(io.read(0x5001, 7, 2).data) == 94
    assert io.read(0x5002, 1, 256).result == AdsReturnCode.DEVICE_INVALID_GROUP
    assert io.read(0x5001, 99, 4).result == AdsReturnCode.DEVICE_INVALID_OFFSET
    assert io.read(0x5001, 5, 2).result == AdsReturnCode.DEVICE_INVALID_SIZE


def test_every_port_reads_state_run(target: SimTarget) -> None:
    probes = [
        device(target).at(300),
        device(target).at(10000),
        device(target),
        master(target),
        master(target).at(1005),
    ]
    for probe in probes:
        assert probe.read_state().ads_state == AdsState.RUN


def test_master_answers_state_count_and_addresses(target: SimTarget) -> None:
    probe = master(target)
    assert probe.device_info().name == "EtherCAT Master"
    state = probe.read(EtherCatMasterGroup.MASTER_STATE, 0x100, 2)
    assert decode_master_state(state.data) == AlState.OP
    count = probe.read(EtherCatMasterGroup.SLAVE_COUNT, 0, 2)
    assert decode_slave_count(count.data) == SLAVES
    addresses = probe.read(EtherCatMasterGroup.SLAVE_ADDRESSES, 0, 2 * SLAVES)
    assert decode_slave_addresses(addresses.data) == tuple(range(1001, 1001 + SLAVES))
    short = probe.read(EtherCatMasterGroup.SLAVE_ADDRESSES, 0, 2 * SLAVES - 2)
    assert short.result == AdsReturnCode.DEVICE_INVALID_SIZE


def test_master_reports_identities_from_the_terminal_yaml(target: SimTarget) -> None:
    probe = master(target)
    answer = probe.read(EtherCatMasterGroup.SLAVE_IDENTITY, 1005, 16)
    identity = SlaveIdentity.decode(answer.data)
    assert identity == SlaveIdentity(2, 0x0C203052, 0x00110000, 0)  # EL3104
    unknown = probe.read(EtherCatMasterGroup.SLAVE_IDENTITY, 4711, 16)
    assert unknown.result == AdsReturnCode.DEVICE_INVALID_OFFSET


def test_master_counters(target: SimTarget) -> None:
    probe = master(target)
    crc = probe.read(EtherCatMasterGroup.SLAVE_CRC_COUNTERS, 1001, 16)
    assert CrcCounters.decode(crc.data) == CrcCounters()
    frames = probe.read(EtherCatMasterGroup.FRAME_COUNTERS, 0, 20)
    assert FrameCounters.decode(frames.data).cyclic_lost == 0
    assert probe.read(0x77, 0, 4).result == AdsReturnCode.DEVICE_INVALID_GROUP
    assert probe.write(EtherCatMasterGroup.SLAVE_COUNT, 0, b"\0\0").result == (
        AdsReturnCode.DEVICE_INVALID_ACCESS
    )


def test_al_states_with_link_status_follow_faults() -> None:
    target = demo_target()
    probe = master(target)

    def states() -> tuple[SlaveState, ...]:
        answer = probe.read(EtherCatMasterGroup.SLAVE_STATES, 0, 2 * SLAVES)
        return decode_slave_states(answer.data)

    assert all(s == SlaveState.of(AlState.OP) for s in states())
    target.set_slave_state(1005, "PREOP")
    target.set_slave_state(EL1014, AlState.SAFEOP)
    target.set_link_lost(1003, True)
    now = states()
    assert now[4].al_state == AlState.PREOP
    assert now[1].al_state == AlState.SAFEOP
    assert now[2].link_state == LinkState.NOT_PRESENT
    assert now[1].link_state == LinkState.MISSING_LINK | LinkState.PORT_B
    one = probe.read(EtherCatMasterGroup.SLAVE_STATES, 1005, 2)
    assert SlaveState.decode(one.data).al_state == AlState.PREOP
    target.set_slave_state(None, "INIT")
    assert {s.al_state for s in states()} == {AlState.INIT}
    target.clear_faults()
    assert all(s == SlaveState.of(AlState.OP) for s in states())


def test_requesting_a_master_state_moves_every_slave() -> None:
    target = demo_target()
    probe = master(target)
    assert probe.write(EtherCatMasterGroup.MASTER_STATE, AlState.PREOP, b"").result == 0
    state = probe.read(EtherCatMasterGroup.MASTER_STATE, 0x100, 2)
    assert decode_master_state(state.data) == AlState.PREOP
    answer = probe.read(EtherCatMasterGroup.SLAVE_STATES, 0, 2 * SLAVES)
    assert {s.al_state for s in decode_slave_states(answer.data)} == {AlState.PREOP}
    assert target.get_symbol_value(f"{EL1014}.WcState.WcState") is True
    bad = probe.write(EtherCatMasterGroup.MASTER_STATE, 7, b"")
    assert bad.result == AdsReturnCode.DEVICE_INVALID_OFFSET
    target.clear_faults()
    assert target.get_symbol_value(f"{EL1014}.WcState.WcState") is False


def test_frame_counters_count_cycles_and_lost_frames() -> None:
    target = demo_target()
    probe = master(target)
    for step in range(5):
        target.tick(step * 0.01)
    first = FrameCounters.decode(
        probe.read(EtherCatMasterGroup.FRAME_COUNTERS, 0, 20).data
    )
    assert first.cyclic_sent >= 4
    target.set_link_lost(1001, True)
    for step in range(5, 10):
        target.tick(step * 0.01)
    later = FrameCounters.decode(
        probe.read(EtherCatMasterGroup.FRAME_COUNTERS, 0, 20).data
    )
    assert later.cyclic_sent > first.cyclic_sent
    assert later.cyclic_lost > 0


def test_master_coe_names_its_slaves(target: SimTarget) -> None:
    probe = master(target)
    vendor = probe.read(IndexGroup.COE_SDO, 0x1018 << 16 | 1, 4)
    assert int.from_bytes(vendor.data, "little") == 2
    kind = probe.read(IndexGroup.COE_SDO, (0x8000 + 4) << 16 | 2, 64)
    name = probe.read(IndexGroup.COE_SDO, (0x8000 + 4) << 16 | 3, 64)
    assert (kind.data, name.data) == (b"EL3104", EL3104_COMPACT.encode())
    missing = probe.read(IndexGroup.COE_SDO, (0x8000 + SLAVES) << 16 | 2, 64)
    assert missing.result == AdsReturnCode.DEVICE_INVALID_OFFSET


def test_stop_answers_read_state_6_everywhere() -> None:
    target = demo_target()
    target.set_run_state(False)
    for probe in (device(target).at(300), device(target), master(target).at(1001)):
        assert probe.read_state().ads_state == AdsState.STOP
    assert (
        decode_master_state(
            master(target).read(EtherCatMasterGroup.MASTER_STATE, 0x100, 2).data
        )
        == AlState.INIT
    )
    target.clear_faults()
    assert device(target).read_state().ads_state == AdsState.RUN


def test_system_service_starts_and_stops_the_runtime() -> None:
    target = demo_target()
    system = device(target).at(10000)
    assert system.write_control(AdsState.STOP).result == 0
    assert device(target).read_state().ads_state == AdsState.STOP
    assert system.write_control(AdsState.RUN).result == 0
    assert device(target).read_state().ads_state == AdsState.RUN
    assert (
        system.write_control(AdsState.POWER_GOOD).result
        == AdsReturnCode.DEVICE_INVALID_DATA
    )
    assert device(target).write_control(AdsState.STOP).result == (
        AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
    )


def test_forced_errors_answer_in_the_result_field() -> None:
    target = demo_target()
    probe = device(target)
    target.force_error(AdsReturnCode.DEVICE_BUSY, group=IndexGroup.SYM_UPLOAD_INFO_2)
    assert (
        probe.read(IndexGroup.SYM_UPLOAD_INFO_2, 0, 24).result
        == AdsReturnCode.DEVICE_BUSY
    )
    assert probe.read(IndexGroup.SYM_VERSION, 0, 1).result == 0
    assert target.read(probe.address, IndexGroup.SYM_UPLOAD_INFO_2, 0, 24)[0] == (
        AdsReturnCode.DEVICE_BUSY
    )
    target.force_error(AdsReturnCode.DEVICE_NOT_READY)
    assert probe.read_state().result == AdsReturnCode.DEVICE_NOT_READY
    target.clear_faults()
    assert probe.read(IndexGroup.SYM_UPLOAD_INFO_2, 0, 24).result == 0


def test_bad_payloads_answer_with_the_codec_return_code(target: SimTarget) -> None:
    probe = device(target)
    sent = probe.packet(ReadRequest(IndexGroup.SYM_VERSION, 0, 1))
    broken = replace(sent, payload=sent.payload[:-2])
    answer = target.handle(broken)
    assert answer is not None and answer.error_code == 0
    assert (
        int.from_bytes(answer.payload[:4], "little")
        == AdsReturnCode.DEVICE_INVALID_SIZE
    )


def test_responses_and_notifications_get_no_answer(target: SimTarget) -> None:
    sent = device(target).packet(ReadRequest(IndexGroup.SYM_VERSION, 0, 1))
    assert target.handle(sent.response(b"\0" * 8)) is None


def test_describe_counts_masters_slaves_and_symbols() -> None:
    target = target_from_text(
        "masters:\n- slaves: [{type: EK1100}, {type: EL1014}]\n"
        "- slaves: [{type: EK1100}, {type: EL2024}, {type: EL3104}]\n"
    )
    summary = target.describe()
    assert summary["slaves"] == 5
    assert [m["slaves"] for m in summary["masters"]] == [2, 3]
    assert [m["ads_port"] for m in summary["masters"]] == [27905, 27906]
    assert summary["symbols"] == sum(m["symbols"] for m in summary["masters"])
    assert summary["net_id"] == "127.0.0.1.1.1"


def test_slave_selection_by_device_and_unknown_slaves() -> None:
    target = target_from_text(
        "masters:\n- slaves: [{type: EK1100}]\n"
        "- slaves: [{type: EK1100}, {type: EL1014}]\n"
    )
    target.set_slave_state(1002, "PREOP", device=2)
    second = target.devices[1].ethercat.slaves[1]
    assert second.al_state == AlState.PREOP
    with pytest.raises(KeyError):
        target.set_slave_state(1002, "PREOP", device=1)
    with pytest.raises(KeyError):
        target.set_link_lost("Term 99 (EL9999)", True)


def test_probe_errors_carry_the_ams_code(target: SimTarget) -> None:
    with pytest.raises(ProbeError) as caught:
        device(target).at(851).read_state()
    assert caught.value.code == AdsReturnCode.TARGET_PORT_NOT_FOUND
