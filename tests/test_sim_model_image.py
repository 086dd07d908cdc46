"""Process images: the image groups, outputs kept, inputs driven by seeded
generators, and what faults do to inputs and WcState."""

from __future__ import annotations

import itertools
import struct

import pytest

from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ads.symbols import AdsSymbolEntry
from fastcs_ethercat.chain.file import load_chain
from fastcs_ethercat.sim.probe import SimProbe
from fastcs_ethercat.twincat.layout import INPUTS, OUTPUTS
from fastcs_ethercat.twincat.target import SimTarget
from tests.test_sim_model_support import (
    EL1014,
    EL1502_TWO_COUNTERS,
    EL2024,
    EL3104_COMPACT,
    EL3104_STANDARD,
    EL3702,
    EL4134,
    REPO_ROOT,
    demo_target,
    device,
    info_by_name,
    registry,
    target_from_text,
    value_by_name,
)

CYCLE = 0.01


def run(target: SimTarget, cycles: int, start: int = 0) -> None:
    for step in range(start, start + cycles):
        target.tick(step * CYCLE)


def entry(probe: SimProbe, name: str) -> AdsSymbolEntry:
    return AdsSymbolEntry.decode(info_by_name(probe, name).data)


def test_image_sizes_and_groups() -> None:
    target = demo_target()
    probe = device(target)
    layout = target.devices[0].layout
    inputs = probe.read(INPUTS.size_group, 0, 4)
    outputs = probe.read(OUTPUTS.size_group, 0, 4)
    assert struct.unpack("<I", inputs.data)[0] == layout.input_size
    assert struct.unpack("<I", outputs.data)[0] == layout.output_size
    whole = probe.read(INPUTS.byte_group, 0, layout.input_size)
    assert len(whole.data) == layout.input_size
    past = probe.read(INPUTS.byte_group, layout.input_size - 1, 2)
    assert past.result == AdsReturnCode.DEVICE_INVALID_SIZE
    beyond = probe.read(INPUTS.byte_group, layout.input_size + 1, 1)
    assert beyond.result == AdsReturnCode.DEVICE_INVALID_OFFSET


def test_outputs_written_through_the_image_read_back_by_name() -> None:
    target = demo_target()
    probe = device(target)
    channel = entry(probe, f"{EL4134}.AO Output Channel 2")
    assert channel.index_group == IndexGroup.IO_IMAGE_RW_INPUT_BYTES  # 0xF020
    written = probe.write(
        channel.index_group, channel.index_offset, struct.pack("<h", 12345)
    )
    assert written.result == 0
    run(target, 20)
    assert target.get_symbol_value(f"{EL4134}.AO Output Channel 2") == 12345
    assert value_by_name(probe, f"{EL4134}.AO Output Channel 2", 2).data == struct.pack(
        "<h", 12345
    )
    bit = entry(probe, f"{EL2024}.Channel 4")
    assert probe.write(bit.index_group, bit.index_offset, b"\x01").result == 0
    assert probe.read(bit.index_group, bit.index_offset, 1).data == b"\x01"
    assert target.get_symbol_value(f"{EL2024}.Channel 4") is True
    assert target.get_symbol_value(f"{EL2024}.Channel 3") is False


def test_bit_groups_move_one_byte_per_bit() -> None:
    target = demo_target()
    probe = device(target)
    first = entry(probe, f"{EL2024}.Channel 1")
    assert (
        probe.write(first.index_group, first.index_offset, b"\x01\x00\x07\x00").result
        == 0
    )
    values = [target.get_symbol_value(f"{EL2024}.Channel {n}") for n in range(1, 5)]
    assert values == [True, False, True, False]
    assert (
        probe.read(first.index_group, first.index_offset, 4).data == b"\x01\x00\x01\x00"
    )


def test_set_symbol_value_encodes_per_type() -> None:
    target = demo_target()
    counter = f"{EL1502_TWO_COUNTERS}.CNT Outputs Channel 2"
    target.set_symbol_value(counter, {"Set counter value": 4_000_000_000})
    target.set_symbol_value(f"{counter}.Control.Set counter", True)
    value = target.get_symbol_value(counter)
    assert value["Set counter value"] == 4_000_000_000
    assert value["Control"]["Set counter"] is True
    with pytest.raises(KeyError):
        target.get_symbol_value("no such symbol")
    with pytest.raises(ValueError):
        target.set_symbol_value(f"{EL4134}.AO Output Channel 1", 40000)


def test_inputs_move_every_cycle_and_outputs_stay() -> None:
    target = demo_target()
    target.set_symbol_value(f"{EL4134}.AO Output Channel 1", 777)
    run(target, 3)
    before = target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel 1")
    counter = target.get_symbol_value(
        f"{EL1502_TWO_COUNTERS}.CNT Inputs Channel 1.Counter value"
    )
    run(target, 3, start=3)
    assert target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel 1") != before
    assert (
        target.get_symbol_value(
            f"{EL1502_TWO_COUNTERS}.CNT Inputs Channel 1.Counter value"
        )
        == counter + 3
    )
    assert target.get_symbol_value(f"{EL4134}.AO Output Channel 1") == 777


def test_signals_are_deterministic_under_a_seed() -> None:
    def trace(seed: int, stride: int) -> list[object]:
        target = demo_target(seed)
        values = []
        for step in range(0, 200, stride):
            target.tick(step * CYCLE)
            if step % 20 == 0:
                values.append(target.devices[0].image.inputs[:])
        return values

    assert trace(7, 1) == trace(7, 1)
    # The values depend on the cycle, not on how often the cycle is polled.
    assert trace(7, 1)[-1] == trace(7, 20)[-1]
    assert trace(7, 1)[-1] != trace(8, 1)[-1]


def test_every_leaf_has_its_own_stream() -> None:
    target = demo_target()
    traces: dict[str, list[bool]] = {}
    for step in range(0, 6000, 100):
        target.tick(step * CYCLE)
        for terminal in (EL1014, "Term 19 (EL1014)"):
            for channel in range(1, 5):
                name = f"{terminal}.Channel {channel}"
                traces.setdefault(name, []).append(target.get_symbol_value(name))
    patterns = {tuple(trace) for trace in traces.values()}
    assert len(patterns) == len(traces)
    assert all(0 < sum(trace) < len(trace) for trace in traces.values())
    compact = [
        target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel {n}")
        for n in range(1, 5)
    ]
    assert len(set(compact)) == 4  # each sine has its own phase


def test_chain_generators_per_terminal_and_per_symbol() -> None:
    target = target_from_text(
        """
system: {task_cycle_ms: 10}
masters:
- slaves:
  - type: EL3104
    pdo_group: Compact
    signal: {kind: counter, start: 5, step: 2}
    signals:
      AI Compact Channel 2: {kind: constant, value: -42}
      AI Compact Channel 3: {kind: ramp, minimum: 0, maximum: 1000, period_s: 1.0}
  - type: EL1014
    signals:
      Channel 1: {kind: constant, value: 1}
      Channel 2.Input: {kind: constant, value: 1}
"""
    )
    run(target, 26)
    name = "Term 1 (EL3104).AI Compact Channel {}"
    assert target.get_symbol_value(name.format(1)) == 5 + 2 * 25
    assert target.get_symbol_value(name.format(2)) == -42
    assert target.get_symbol_value(name.format(3)) == 250
    assert target.get_symbol_value("Term 2 (EL1014).Channel 1") is True
    assert target.get_symbol_value("Term 2 (EL1014).Channel 2") is True


def test_default_signals_by_name() -> None:
    target = demo_target()
    run(target, 12)
    standard = target.get_symbol_value(f"{EL3104_STANDARD}.AI Standard Channel 1")
    assert standard["Status"]["Error"] is False
    assert standard["Status"]["TxPDO Toggle"] in (True, False)
    samples = target.get_symbol_value(f"{EL3702}.Ch1 Sample 0")
    assert len(samples) == 10
    # The samples of one cycle follow one smooth signal.
    steps = [abs(b - a) for a, b in itertools.pairwise(samples)]
    assert max(steps) < 3000
    cycle_counts = target.get_symbol_value(f"{EL3702}.Ch1 CycleCount")
    run(target, 1, start=12)
    assert (
        target.get_symbol_value(f"{EL3702}.Ch1 CycleCount")
        == (cycle_counts + 1) % 65536
    )


def test_a_set_input_keeps_its_value_until_faults_clear() -> None:
    target = demo_target()
    name = f"{EL3104_COMPACT}.AI Compact Channel 4"
    target.set_symbol_value(name, 321)
    run(target, 10)
    assert target.get_symbol_value(name) == 321
    target.clear_faults()
    run(target, 10, start=10)
    assert target.get_symbol_value(name) != 321


def test_inputs_written_over_ads_are_overwritten_next_cycle() -> None:
    target = demo_target()
    probe = device(target)
    compact = entry(probe, f"{EL3104_COMPACT}.AI Compact Channel 1")
    run(target, 1)
    probe.write(compact.index_group, compact.index_offset, struct.pack("<h", 5))
    assert target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel 1") == 5
    run(target, 1, start=1)
    assert target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel 1") != 5


def test_a_slave_out_of_op_freezes_its_inputs_and_flags_its_datagram() -> None:
    target = demo_target()
    run(target, 3)
    inputs_wc = f"{EL1014}.WcState.WcState"
    assert target.get_symbol_value(inputs_wc) is False
    target.set_slave_state(EL3104_COMPACT, "PREOP")
    frozen = target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel 1")
    moving = target.get_symbol_value(f"{EL3104_STANDARD}.AI Standard Channel 1.Value")
    run(target, 5, start=3)
    assert target.get_symbol_value(f"{EL3104_COMPACT}.AI Compact Channel 1") == frozen
    assert (
        target.get_symbol_value(f"{EL3104_STANDARD}.AI Standard Channel 1.Value")
        != moving
    )
    # Every terminal in the inputs-only datagram sees the bad working counter.
    assert target.get_symbol_value(f"{EL3104_COMPACT}.WcState.WcState") is True
    assert target.get_symbol_value(inputs_wc) is True
    assert target.get_symbol_value(f"{EL2024}.WcState.WcState") is False
    device_inputs = target.get_symbol_value("Device 1 (EtherCAT).Inputs")
    assert device_inputs["Frm0WcState"] & 0b1000
    target.clear_faults()
    run(target, 2, start=8)
    assert target.get_symbol_value(inputs_wc) is False


def test_lost_link_shows_in_the_master_inputs() -> None:
    target = demo_target()
    run(target, 2)
    target.set_link_lost(f"{EL2024}", True)
    run(target, 2, start=2)
    inputs = target.get_symbol_value("Device 1 (EtherCAT).Inputs")
    assert inputs["SlaveCount"] == 23
    assert inputs["DevState"] != 0
    assert target.get_symbol_value(f"{EL2024}.WcState.WcState") is True


def test_input_toggle_flips_while_data_flows() -> None:
    target = demo_target()
    toggles = []
    for step in range(4):
        target.tick(step * CYCLE)
        toggles.append(target.get_symbol_value(f"{EL1014}.WcState.InputToggle"))
    assert toggles in ([True, False, True, False], [False, True, False, True])


def test_stop_freezes_inputs() -> None:
    target = demo_target()
    run(target, 3)
    target.set_run_state(False)
    before = bytes(target.devices[0].image.inputs)
    run(target, 5, start=3)
    assert bytes(target.devices[0].image.inputs) == before
    target.set_run_state(True)
    run(target, 2, start=8)
    assert bytes(target.devices[0].image.inputs) != before


def test_clearing_images_through_0xf040_and_0xf050() -> None:
    target = demo_target()
    probe = device(target)
    target.set_symbol_value(f"{EL4134}.AO Output Channel 1", 99)
    assert probe.write(IndexGroup.IO_IMAGE_CLEAR_INPUTS, 0, b"").result == 0
    assert target.get_symbol_value(f"{EL4134}.AO Output Channel 1") == 0


def test_a_rack_of_over_100_terminals_builds() -> None:
    chain = load_chain(REPO_ROOT / "ioc" / "rack-chain.yaml")
    target = SimTarget(chain, registry())
    summary = target.describe()
    assert summary["slaves"] >= 100
    assert summary["symbols"] > 400
    run(target, 3)
    assert target.get_symbol_value("Term 62 (EL1502).CNT Inputs.Counter value") >= 2
