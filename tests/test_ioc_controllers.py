"""The controller tree from a hand-built plan, without ADS or EPICS.

Attributes are checked directly (FastCS objects, no transport), so these run
in-process and fast; the end-to-end path is in test_ioc_demo.
"""

from __future__ import annotations

import enum
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastcs.attributes import AttrR, AttrRW
from fastcs.datatypes import Bool, Enum, Int, Waveform

from fastcs_ethercat.ads.ethercat import (
    AlState,
    AlStateFlag,
    FrameCounters,
    SlaveState,
)
from fastcs_ethercat.ioc.app import poll_groups
from fastcs_ethercat.ioc.attributes import CoeIO
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.ioc.controllers.master import MasterStatus
from fastcs_ethercat.ioc.controllers.terminal import (
    AlStateView,
    GenericTerminalController,
    TerminalController,
    al_state_text,
)
from fastcs_ethercat.ioc.controllers.tree import Tree, build_tree
from fastcs_ethercat.ioc.datatypes import ExactFloat, IntegralFloat
from fastcs_ethercat.ioc.plan import (
    CoePoint,
    MasterPlan,
    Point,
    PointKind,
    SlaveInfo,
    SystemPlan,
    TerminalPlan,
)

MASTER = "Device 1 (EtherCAT)"
COUPLER = "Term 1 (EK1100)"
ANALOG = "Term 2 (EL3104)"
UNKNOWN = "Term 3 (EL9999)"


def _point(symbol: str, type_name: str, **extra: Any) -> Point:
    kind = extra.pop("kind", PointKind.SCALAR)
    return Point(
        key=f"1/{symbol}",
        symbol=symbol,
        attribute=symbol.lower().replace(" ", "_"),
        type_name=type_name,
        kind=kind,
        index_group=0xF020,
        index_offset=0,
        byte_size=extra.pop("byte_size", 2),
        **extra,
    )


ANALOG_POINTS = [
    _point(f"{ANALOG}.AI Standard Channel 1.Value", "INT", units="V"),
    _point(
        f"{ANALOG}.AI Standard Channel 1.Status.Overrange", "BIT", kind=PointKind.BIT
    ),
    _point(
        f"{ANALOG}.AI Standard Channel 1.Status.Limit 1",
        "BIT2",
        kind=PointKind.BITS,
        bit_size=2,
    ),
    _point(f"{ANALOG}.Scaled", "LREAL", byte_size=8),
    _point(f"{ANALOG}.Counter", "UDINT", byte_size=4),
    _point(
        f"{ANALOG}.Mode",
        "USINT",
        writable=True,
        enum_texts=((0, "Signed"), (1, "Unsigned"), (5, "Absolute MSB sign")),
    ),
    _point(f"{ANALOG}.Samples", "INT", kind=PointKind.ARRAY, length=10),
    _point(f"{ANALOG}.AO Output", "SINT", writable=True, byte_size=1),
    _point(f"{ANALOG}.Strange", "NO_SUCH_TYPE"),
]
COE = [CoePoint("presentation", 0x8000, 0x02, "DT0800EN03", 3, True,
                enum_texts=((0, "Signed"), (1, "Unsigned")))]  # fmt: skip


def _plan() -> SystemPlan:
    def slave(name: str, position: int, **extra: Any) -> SlaveInfo:
        return SlaveInfo(1001 + position, name, 2, 0x1000 + position, 1,
                         position=position, **extra)  # fmt: skip

    terminals = [
        TerminalPlan(slave(COUPLER, 0, is_coupler=True), "EK1100"),
        TerminalPlan(
            slave(ANALOG, 1, coupler=COUPLER), "EL3104", points=ANALOG_POINTS, coe=COE
        ),
        TerminalPlan(
            slave(UNKNOWN, 2, coupler=COUPLER),
            None,
            points=[_point(f"{UNKNOWN}.Raw", "UINT")],
        ),
    ]
    master = MasterPlan(1, MASTER, "127.0.0.1.2.1", 27905, terminals)
    return SystemPlan("127.0.0.1.1.1", "Sim", "3.1.4024", 7, [master])


class Recorder:
    """Stands in for the data plane: remembers writes, serves CoE values."""

    def __init__(self) -> None:
        self.writes: list[tuple[str, Any]] = []
        self.coe: dict[int, Any] = {2: 1}
        self.fail_coe = False

    async def write(self, point: Point, value: Any) -> None:
        self.writes.append((point.symbol, value))

    async def read_coe(self, coe: CoePoint) -> Any:
        if self.fail_coe:
            raise TimeoutError("no answer")
        return self.coe[coe.subindex]

    async def write_coe(self, coe: CoePoint, value: Any) -> None:
        self.coe[coe.subindex] = value


def _tree(recorder: Recorder, **extra: Any) -> Tree:
    """The tree, with its IOs connected as FastCS does before serving."""
    tree = build_tree(
        _plan(),
        "TEST",
        target="sim",
        writer=recorder.write,
        coe_access=lambda m, t: (recorder.read_coe, recorder.write_coe),
        **extra,
    )
    tree.root.post_initialise()
    return tree


def _analog(tree: Tree) -> TerminalController:
    terminal = tree.masters[0].terminals[1002]
    assert isinstance(terminal, TerminalController)
    return terminal


def test_tree_levels_and_names_follow_the_default_scheme() -> None:
    tree = _tree(Recorder())
    names = [entry.name for entry in tree.pvs()]

    assert "TEST:ETH1:RIO1:MOD2:AIStdCh1Value" in names
    assert "TEST:ETH1:RIO1:MOD2:Mode_RBV" in names
    assert "TEST:ETH1:RIO1:MOD2:CoePresentation" in names
    assert "TEST:ETH1:RIO1:MOD2:CoeRefresh" in names
    assert "TEST:ETH1:RIO1:MOD3:Raw" in names
    assert "TEST:ETH1:RIO1:AlState" in names
    assert "TEST:ETH1:SlaveCount" in names
    assert "TEST:PollRate" in names
    assert all(len(name) <= 60 for name in names)
    assert [e.line() for e in tree.pvs()] == [e.line() for e in _tree(Recorder()).pvs()]


def test_types_keep_width_signedness_and_precision() -> None:
    terminal = _analog(_tree(Recorder()))
    by_symbol = {a.io_ref.point.symbol: a for a in terminal.by_key.values()}

    def datatype(name: str) -> Any:
        return by_symbol[f"{ANALOG}.{name}"].datatype

    assert datatype("AI Standard Channel 1.Value") == Int(
        units="V", min=-32768, max=32767
    )
    assert isinstance(datatype("AI Standard Channel 1.Status.Overrange"), Bool)
    assert datatype("AI Standard Channel 1.Status.Limit 1") == Int(min=0, max=3)
    assert isinstance(datatype("Scaled"), ExactFloat)
    assert datatype("Scaled").validate(1.2345678901234567) == 1.2345678901234567
    assert isinstance(datatype("Counter"), IntegralFloat)
    assert isinstance(datatype("Mode"), Enum)
    assert isinstance(datatype("Samples"), Waveform)
    assert datatype("Samples").shape == (10,)
    assert isinstance(by_symbol[f"{ANALOG}.AO Output"], AttrRW)
    assert not isinstance(by_symbol[f"{ANALOG}.Counter"], AttrRW)


def test_a_point_without_a_pv_form_is_reported_not_dropped() -> None:
    tree = _tree(Recorder())

    assert [source for source, _ in tree.unserved()] == [f"{ANALOG}.Strange"]
    assert tree.root.unserved == 1


def test_read_only_serves_outputs_and_coe_read_only() -> None:
    tree = _tree(Recorder(), read_only=True)
    entries = {e.name: e for e in tree.pvs()}

    assert entries["TEST:ETH1:RIO1:MOD2:AOOutput"].access == "r"
    assert entries["TEST:ETH1:RIO1:MOD2:CoePresentation"].access == "r"


def test_unknown_type_gets_the_generic_controller() -> None:
    tree = _tree(Recorder())
    generic = tree.masters[0].terminals[1003]

    assert isinstance(generic, GenericTerminalController)
    assert generic.diag["Type"].get() == "unknown"
    assert "0x1002" in (generic.description or "")


async def test_changes_are_posted_and_a_bad_value_only_marks_its_point() -> None:
    terminal = _analog(_tree(Recorder()))
    mode = next(p for p in ANALOG_POINTS if p.symbol.endswith(".Mode"))
    value = ANALOG_POINTS[0]
    samples = next(p for p in ANALOG_POINTS if p.symbol.endswith(".Samples"))

    await terminal.apply_change(value, -1234)
    await terminal.apply_change(mode, 5)
    await terminal.apply_change(mode, 3)  # not a member: must not raise
    await terminal.apply_change(samples, np.arange(10, dtype=np.int16))

    assert terminal.by_key[value.key].get() == -1234
    mode_value = terminal.by_key[mode.key].get()
    assert isinstance(mode_value, enum.Enum) and mode_value.value == 5
    assert list(terminal.failed_points) == [mode.key]
    assert terminal.by_key[samples.key].get().tolist() == list(range(10))


async def test_writes_reach_the_writer_as_plain_values() -> None:
    recorder = Recorder()
    terminal = _analog(_tree(recorder))
    mode = terminal.by_key[next(p.key for p in ANALOG_POINTS if "Mode" in p.symbol)]
    output = terminal.by_key[next(p.key for p in ANALOG_POINTS if "AO" in p.symbol)]
    assert isinstance(mode, AttrRW) and isinstance(output, AttrRW)

    await mode.put(mode.datatype.validate(5), sync_setpoint=False)
    await output.put(-7, sync_setpoint=False)

    assert recorder.writes == [(f"{ANALOG}.Mode", 5), (f"{ANALOG}.AO Output", -7)]
    with pytest.raises(ValueError):
        await output.put(1000)  # beyond SINT


async def test_coe_is_read_on_demand_written_and_read_back() -> None:
    recorder = Recorder()
    terminal = _analog(_tree(recorder))
    (coe,) = terminal.coe_attributes
    io = terminal.coe_io
    assert isinstance(io, CoeIO) and isinstance(coe, AttrRW)

    await terminal.refresh_coe()
    first = coe.get().value
    await coe.put(coe.datatype.validate(0), sync_setpoint=False)
    recorder.fail_coe = True
    await terminal.refresh_coe()  # a failed SDO read must not raise

    assert first == 1
    assert recorder.coe[2] == 0
    assert coe.get().value == 0
    assert "presentation" in io.failures


async def test_master_status_reaches_every_terminal() -> None:
    tree = _tree(Recorder())
    master = tree.masters[0]
    states = (
        SlaveState.of(AlState.OP),
        SlaveState.of(AlState.SAFEOP, AlStateFlag.ERROR, link=0x04),
        SlaveState.of(AlState.OP),
    )
    status = MasterStatus(8, 3, FrameCounters(1, 100, 2, 50, 1), states, {1002: 7})

    await master.apply_status(status)
    analog = _analog(tree)

    assert master.attrs["SlaveCount"].get() == 3
    assert master.attrs["LostFrames"].get() == 3
    assert analog.diag["AlState"].get() is AlStateView.SAFEOP_ERR
    assert analog.diag["AlStateText"].get() == "SAFEOP+ERR"
    assert analog.diag["LinkOk"].get() is False
    assert analog.diag["CrcErrors"].get() == 7
    assert al_state_text(states[0]) == "OP"


async def test_a_failing_master_read_never_raises_out_of_the_scan() -> None:
    async def broken() -> MasterStatus:
        raise ConnectionError("gone")

    tree = _tree(Recorder())
    master = tree.masters[0]
    master.reader = broken

    await master.read_diagnostics()

    assert master.failures == 1
    online = master.attrs["Online"]
    assert isinstance(online, AttrR) and online.get() is False


def test_poll_groups_follow_per_terminal_rates(tmp_path: Path) -> None:
    config_file = tmp_path / "ioc.yaml"
    config_file.write_text(
        "prefix: TEST\ntarget: 127.0.0.1\npoll_rate_hz: 10\n"
        f"terminals:\n  {ANALOG}: {{poll_rate_hz: 50}}\n"
    )
    config = load_ioc_config(config_file)

    groups = poll_groups(config, _plan())

    assert [(g.rate_hz, len(g.points)) for g in groups] == [
        (10.0, 1),
        (50.0, len(ANALOG_POINTS)),
    ]


def test_aliases_pin_segments_and_unknown_ones_are_reported() -> None:
    aliases = {
        MASTER: "ECAT",
        f"{MASTER}^{COUPLER}^{ANALOG}": "PIEZO",
        f"{MASTER}^{COUPLER}^{ANALOG}^AI Standard Channel 1.Value": "Pos1",
        "Device 9 (EtherCAT)": "Nowhere",
    }
    tree = _tree(Recorder(), aliases=aliases)
    names = {entry.name for entry in tree.pvs()}

    assert "TEST:ECAT:RIO1:PIEZO:Pos1" in names
    assert "TEST:ECAT:RIO1:PIEZO:Mode_RBV" in names
    assert tree.names.unused_aliases == ("Device 9 (EtherCAT)",)
