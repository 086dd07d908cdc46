"""The controller tree from a hand-built plan, without ADS or EPICS.

Attributes are checked directly (FastCS objects, no transport), so these run
in-process and fast; the end-to-end path is in test_ioc_demo.
"""

from __future__ import annotations

import asyncio
import enum
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastcs.attributes import AttrR, AttrRW
from fastcs.datatypes import Bool, Enum, Int, Waveform

from fastcs_ethercat.ads.constants import IndexGroup
from fastcs_ethercat.ads.errors import AdsTimeoutError
from fastcs_ethercat.ads.ethercat import (
    AlState,
    AlStateFlag,
    FrameCounters,
    SlaveIdentity,
    SlaveState,
)
from fastcs_ethercat.ioc.alarms import NO_ALARM, Severity, Status, value_alarm
from fastcs_ethercat.ioc.attributes import CoeIO
from fastcs_ethercat.ioc.config import IocConfig, load_ioc_config
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.controllers.master import Batch, MasterStatus
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.ioc.controllers.terminal import (
    AlStateView,
    GenericTerminalController,
    TerminalController,
    al_state_text,
)
from fastcs_ethercat.ioc.datatypes import ExactFloat, IntegralFloat, severity_table
from fastcs_ethercat.ioc.handles import PointHandles
from fastcs_ethercat.ioc.plan import (
    CoePoint,
    MasterPlan,
    Point,
    PointKind,
    SlaveInfo,
    SystemPlan,
    TerminalPlan,
)
from fastcs_ethercat.terminals.meaning import Scaling

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


VOLTS = Scaling(10 / 32767, 0.0, "V")
CHANNEL_1 = {"channel": 1}
ANALOG_POINTS = [
    _point(
        f"{ANALOG}.AI Standard Channel 1.Value",
        "INT",
        scaling=Scaling(unit="V"),
        entry_name="Value",
        **CHANNEL_1,
    ),
    _point(
        f"{ANALOG}.AI Standard Channel 1.Status.Overrange",
        "BIT",
        kind=PointKind.BIT,
        entry_name="Status.Overrange",
        **CHANNEL_1,
    ),
    _point(
        f"{ANALOG}.AI Standard Channel 1.Status.Limit 1",
        "BIT2",
        kind=PointKind.BITS,
        bit_size=2,
        entry_name="Status.Limit 1",
        **CHANNEL_1,
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
    _point(f"{ANALOG}.AI Volts", "INT", scaling=VOLTS, description="EL3104 AI Volts"),
    _point(f"{ANALOG}.AO Volts", "INT", scaling=VOLTS, writable=True),
    _point(f"{ANALOG}.Status.Error", "BIT", kind=PointKind.BIT, severity=2),
]
COE = [CoePoint("presentation", 0x8000, 0x02, "DT0800EN03", 3, True,
                enum_texts=((0, "Signed"), (1, "Unsigned")), name="Presentation",
                object_name="AI Settings")]  # fmt: skip


def _plan() -> SystemPlan:
    def slave(name: str, position: int, **extra: Any) -> SlaveInfo:
        identity = SlaveIdentity(2, 0x1000 + position, 1)
        return SlaveInfo(1001 + position, name, identity, position=position, **extra)

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
    """Stands in for the target's ADS clients: remembers writes, answers SDOs."""

    def __init__(self) -> None:
        self.writes: list[tuple[int, int, bytes]] = []
        self.coe: dict[int, int] = {2: 1}
        self.fail_coe = False

    async def get(self, net_id: str, ams_port: int) -> Recorder:
        return self

    async def read(self, group: int, offset: int, size: int) -> bytes:
        assert group == IndexGroup.COE_SDO
        if self.fail_coe:
            raise TimeoutError("no answer")
        return self.coe[offset & 0xFF].to_bytes(size, "little")

    async def write(self, group: int, offset: int, data: bytes) -> None:
        if group == IndexGroup.COE_SDO:
            self.coe[offset & 0xFF] = int.from_bytes(data, "little")
        else:
            self.writes.append((group, offset, data))

    async def write_by_handle(self, handle: int, data: bytes) -> None:
        self.writes.append((IndexGroup.SYM_VALUE_BY_HANDLE, handle, data))


def _root(
    recorder: Recorder, config: IocConfig | None = None, **extra: Any
) -> RootController:
    """The tree, with its IOs connected as FastCS does before serving."""

    async def no_target() -> Any:
        raise AssertionError("built from the plan, never discovered")

    config = config or IocConfig(prefix="TEST", target="sim", **extra)
    root = RootController(config, no_target)
    connection = Connection(recorder, "127.0.0.1.1.1", read_only=config.read_only)  # type: ignore[arg-type]
    root.build(_plan(), connection)
    root.post_initialise()
    return root


def _analog(root: RootController) -> TerminalController:
    terminal = root.masters[0].terminals[1002]
    assert isinstance(terminal, TerminalController)
    return terminal


def test_tree_levels_and_names_follow_the_default_scheme() -> None:
    root = _root(Recorder())
    names = [entry.name for entry in root.pvs()]

    assert "TEST:ETH1:RIO1:MOD2:CH1:Value" in names
    assert "TEST:ETH1:RIO1:MOD2:CH1:Overrange" in names
    assert "TEST:ETH1:RIO1:MOD2:Mode_RBV" in names
    assert "TEST:ETH1:RIO1:MOD2:C8000:Presentation_RBV" in names
    assert "TEST:ETH1:RIO1:MOD2:CoeRefresh" in names
    assert "TEST:ETH1:RIO1:MOD3:Raw" in names
    assert "TEST:ETH1:RIO1:AlState" in names
    assert "TEST:ETH1:SlaveCount" in names
    assert "TEST:PollRate" in names
    assert all(len(name) <= 60 for name in names)
    assert [e.line() for e in root.pvs()] == [e.line() for e in _root(Recorder()).pvs()]
    assert root.pv_count == len(names)  # counted without listing
    assert any(e.access == "rw" for e in root.pvs())  # and _RBV, counted too


def test_channels_and_coe_objects_are_sub_controllers_of_the_terminal() -> None:
    terminal = _analog(_root(Recorder()))
    channel, coe = terminal.sub_controllers["CH1"], terminal.sub_controllers["C8000"]

    assert list(terminal.sub_controllers) == ["CH1", "C8000"]
    assert list(channel.attributes) == ["Value", "Overrange", "Limit1"]
    assert channel.path == ["TEST", "ETH1", "RIO1", "MOD2", "CH1"]
    assert channel.attributes["Value"] is terminal.by_key[ANALOG_POINTS[0].key]
    assert coe.attributes["Presentation"] is terminal.coe_attributes[0]
    assert coe.description == "CoE 0x8000 AI Settings"
    assert "Mode" in terminal.attributes and "AlState" in terminal.attributes


def test_types_keep_width_signedness_and_precision() -> None:
    terminal = _analog(_root(Recorder()))
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
    root = _root(Recorder())

    assert [source for source, _ in root.unserved_points()] == [f"{ANALOG}.Strange"]
    assert root.unserved == 1


def test_read_only_serves_outputs_and_coe_read_only() -> None:
    root = _root(Recorder(), read_only=True)
    entries = {e.name: e for e in root.pvs()}

    assert entries["TEST:ETH1:RIO1:MOD2:AOOutput"].access == "r"  # no channel
    assert entries["TEST:ETH1:RIO1:MOD2:C8000:Presentation"].access == "r"


def test_unknown_type_gets_the_generic_controller() -> None:
    root = _root(Recorder())
    generic = root.masters[0].terminals[1003]

    assert isinstance(generic, GenericTerminalController)
    assert generic.diag["Type"].get() == "unknown"
    assert "0x1002" in (generic.description or "")


async def test_changes_are_posted_and_a_bad_value_only_marks_its_point() -> None:
    root = _root(Recorder())
    master, terminal = root.masters[0], _analog(root)
    mode = next(p for p in ANALOG_POINTS if p.symbol.endswith(".Mode"))
    value = ANALOG_POINTS[0]
    samples = next(p for p in ANALOG_POINTS if p.symbol.endswith(".Samples"))
    batches: asyncio.Queue[Batch] = asyncio.Queue()
    changes = [
        (value, -1234),
        (mode, 5),
        (mode, 3),
        (samples, np.arange(10, dtype=np.int16)),
    ]
    batches.put_nowait(changes)  # 3 is no member: must not stop the rest
    posting = asyncio.create_task(master._post_batches(batches))
    await asyncio.sleep(0.05)
    posting.cancel()

    assert terminal.by_key[value.key].get() == -1234
    mode_value = terminal.by_key[mode.key].get()
    assert isinstance(mode_value, enum.Enum) and mode_value.value == 5
    assert master.failures == 1 and "Mode" in master.last_error
    assert terminal.by_key[samples.key].get().tolist() == list(range(10))


async def test_writes_go_once_by_the_handle_of_their_symbol() -> None:
    recorder = Recorder()
    root = _root(recorder)
    master, terminal = root.masters[0], _analog(root)
    mode_point = next(p for p in ANALOG_POINTS if "Mode" in p.symbol)
    output_point = next(p for p in ANALOG_POINTS if "AO" in p.symbol)
    master.handles = PointHandles(
        writes={mode_point.symbol: 0x101, output_point.symbol: 0x102}
    )
    mode = terminal.by_key[mode_point.key]
    output = terminal.by_key[output_point.key]
    assert isinstance(mode, AttrRW) and isinstance(output, AttrRW)

    await mode.put(mode.datatype.validate(5), sync_setpoint=False)
    await output.put(-7, sync_setpoint=False)
    master.handles = PointHandles(problems={output_point.symbol: "gone"})
    with pytest.raises(LookupError, match="gone"):
        await output.put(-8, sync_setpoint=False)

    assert recorder.writes == [(0xF005, 0x101, b"\x05"), (0xF005, 0x102, b"\xf9")]
    with pytest.raises(ValueError):
        await output.put(1000)  # beyond SINT


class Stalling(Recorder):
    """A target whose writes time out; the read back answers `held`, or
    times out too when it is None."""

    def __init__(self, held: bytes | None) -> None:
        super().__init__()
        self.held = held

    async def write_by_handle(self, handle: int, data: bytes) -> None:
        raise AdsTimeoutError(0x745, "write", "target")

    async def read_by_handle(self, handle: int, size: int) -> bytes:
        if self.held is None:
            raise AdsTimeoutError(0x745, "read", "target")
        return self.held


@pytest.mark.parametrize(
    ("held", "outcome"),
    [
        (b"\xf9", None),  # applied after all: the put succeeds
        (b"\x00", "the read back shows it was not applied"),
        (None, "outcome unknown"),
    ],
)
async def test_a_write_that_timed_out_is_decided_by_reading_it_back(
    held: bytes | None, outcome: str | None
) -> None:
    root = _root(Stalling(held))
    master, terminal = root.masters[0], _analog(root)
    point = next(p for p in ANALOG_POINTS if "AO" in p.symbol)
    master.handles = PointHandles(writes={point.symbol: 0x102})
    output = terminal.by_key[point.key]
    assert isinstance(output, AttrRW)

    if outcome is None:
        await output.put(-7, sync_setpoint=False)
    else:
        with pytest.raises(Exception, match=outcome):
            await output.put(-7, sync_setpoint=False)


async def test_coe_is_read_on_demand_written_and_read_back() -> None:
    recorder = Recorder()
    terminal = _analog(_root(recorder))
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


def test_a_coe_attribute_is_named_in_one_short_line() -> None:
    """FastCS logs a failed put with its attribute, whose reference holds the
    CoE point: the point shows as its address and name, not every field (a
    long ESI description and enum texts made a line of ~1 000 characters)."""
    wordy = CoePoint(
        "mode", 0x8000, 0x11, "DT0800EN16", 16, True, description="x" * 500,
        enum_texts=tuple((n, f"text {n}") for n in range(50)), name="Mode",
    )  # fmt: skip
    (coe,) = _analog(_root(Recorder())).coe_attributes

    assert repr(wordy) == "CoePoint(0x8000:11 'Mode')"
    assert "CoePoint(0x8000:02 'Presentation')" in repr(coe)
    assert len(repr(coe)) < 200 and "\n" not in repr(coe)


async def test_master_status_reaches_every_terminal() -> None:
    root = _root(Recorder())
    master = root.masters[0]
    states = (
        SlaveState.of(AlState.OP),
        SlaveState.of(AlState.SAFEOP, AlStateFlag.ERROR, link=0x04),
        SlaveState.of(AlState.OP),
    )
    status = MasterStatus(8, 3, FrameCounters(1, 100, 2, 50, 1), states, {1002: 7})

    await master.apply_status(status)
    analog = _analog(root)

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

    root = _root(Recorder())
    master = root.masters[0]
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
    root = _root(Recorder(), load_ioc_config(config_file))

    groups = root.masters[0].groups
    served = len(ANALOG_POINTS) - 1  # "Strange" has no PV form, is not polled
    assert [(g.rate_hz, len(g.points)) for g in groups] == [(10.0, 1), (50.0, served)]


def test_aliases_pin_segments_and_unknown_ones_are_reported() -> None:
    aliases = {
        MASTER: "ECAT",
        f"{MASTER}^{COUPLER}^{ANALOG}": "PIEZO",
        f"{MASTER}^{COUPLER}^{ANALOG}^AI Standard Channel 1.Value": "Pos1",
        "Device 9 (EtherCAT)": "Nowhere",
    }
    root = _root(Recorder(), pv_aliases=aliases)
    names = {entry.name for entry in root.pvs()}

    assert "TEST:ECAT:RIO1:PIEZO:CH1:Pos1" in names
    assert "TEST:ECAT:RIO1:PIEZO:Mode_RBV" in names
    assert root.names.unused_aliases == ("Device 9 (EtherCAT)",)


def _by_name(root: RootController) -> dict[str, Any]:
    """Every attribute of the analog terminal by its PV segment."""
    return {name: attr for name, attr in _analog(root).attributes.items()}


async def test_a_scaled_value_is_served_in_its_unit_with_its_raw_count() -> None:
    recorder = Recorder()
    root = _root(recorder)
    master, terminal = root.masters[0], _analog(root)
    served = {e.name: e for e in root.pvs()}
    attrs = _by_name(root)
    volts_in, raw_in = attrs["AIVolts"], attrs["AIVoltsRaw"]
    volts_out, raw_out = attrs["AOVolts"], attrs["AOVoltsRaw"]
    point_in = next(p for p in ANALOG_POINTS if p.symbol.endswith("AI Volts"))
    batches: asyncio.Queue[Batch] = asyncio.Queue()
    batches.put_nowait([(point_in, 16384)])
    posting = asyncio.create_task(master._post_batches(batches))
    await asyncio.sleep(0.05)
    posting.cancel()
    assert isinstance(volts_out, AttrRW)
    point_out = next(p for p in ANALOG_POINTS if p.symbol.endswith("AO Volts"))
    master.handles = PointHandles(problems={point_out.symbol: "gone"})
    with pytest.raises(LookupError, match="gone"):  # the setpoint says so
        await volts_out.put(2.5, sync_setpoint=False)
    refused = master.health.setpoint_alarm(volts_out)
    master.handles = PointHandles(writes={point_out.symbol: 0x103})
    await volts_out.put(2.5, sync_setpoint=False)

    assert served["TEST:ETH1:RIO1:MOD2:AIVolts"].datatype == "ExactFloat"
    assert served["TEST:ETH1:RIO1:MOD2:AIVoltsRaw"].access == "r"
    assert served["TEST:ETH1:RIO1:MOD2:AOVoltsRaw"].access == "r"
    assert volts_in.datatype.units == "V" and volts_in.datatype.prec == 4
    assert (raw_in.get(), volts_in.get()) == (16384, pytest.approx(5.0002, abs=1e-4))
    assert terminal.by_key[point_in.key] is raw_in  # the poller feeds the raw
    assert not isinstance(raw_out, AttrRW)
    assert recorder.writes[-1] == (0xF005, 0x103, (8192).to_bytes(2, "little"))
    assert (refused.severity, refused.status) == (Severity.INVALID, Status.WRITE)
    assert master.health.setpoint_alarm(volts_out) == NO_ALARM  # written
    assert master.shown_by_key[point_out.key] is volts_out
    assert volts_in.description == "EL3104 AI Volts"
    assert raw_in.description == "EL3104 AI Volts raw"
    with pytest.raises(ValueError):
        await volts_out.put(10.5)  # beyond the INT's 10 V


async def test_status_bits_and_diagnostics_carry_their_severity() -> None:
    root = _root(Recorder())
    master, analog = root.masters[0], _analog(root)
    states = (
        SlaveState.of(AlState.OP),
        SlaveState.of(AlState.SAFEOP, link=0x04),
        SlaveState.of(AlState.OP),
    )
    await master.apply_status(MasterStatus(8, 3, FrameCounters(), states, {}))

    error = _by_name(root)["StatusError"]
    assert severity_table(error.datatype) is not None
    assert severity_table(error.datatype)(True) == 2
    assert value_alarm(analog.diag["AlState"]).severity is Severity.MAJOR
    assert value_alarm(analog.diag["LinkOk"]).severity is Severity.MAJOR
    assert master.attrs["State"].get() is AlStateView.OP
    assert value_alarm(master.attrs["State"]).severity is Severity.NO_ALARM
    assert value_alarm(master.attrs["Online"]) == NO_ALARM
    assert value_alarm(root.attrs["Connected"]).severity is Severity.MAJOR  # False
    assert value_alarm(root.attrs["ConnectionState"]).severity is Severity.MAJOR
