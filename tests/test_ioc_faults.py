"""The IOC under every fault the simulator can inject: alarms and recovery.

One simulator and one IOC subprocess serve the whole module; every test
clears its faults and waits until the IOC serves every PV again. Alarm
times come from p4p monitors (PVA carries severity with every update), so
a figure is the time from the fault request to the first update with the
expected severity. The figures are printed (run with `-s` to see them).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from fastcs.attributes import AttrR
from fastcs.datatypes import Int

from fastcs_ethercat.ads.ethercat import SlaveIdentity
from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.encode import check_write
from fastcs_ethercat.ioc.health import COMM, Health
from fastcs_ethercat.ioc.plan import (
    MasterPlan,
    Point,
    PointKind,
    SlaveInfo,
    SystemPlan,
    TerminalPlan,
)
from fastcs_ethercat.ioc.reconnect import chain_changes
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IocProcess,
    caget,
    served_ioc,
    terminals_with_coe,
    wait_for,
    write_ioc_config,
)

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
INVALID = 3
SINE = "ETH1:RIO1:MOD5:CH1:Value"  # Term 5 (EL3104): moves all the time
STEADY = "ETH1:RIO21:MOD22:CH1:ValueRaw"  # Term 22 (EL3104): set by tests
STEADY_SYMBOL = "Term 22 (EL3104).AI Standard Channel 1.Value"
OUTPUT = "Term 24 (EP4374-0002).AO Outputs Channel 3"
NEIGHBOUR = "ETH1:RIO21:MOD22:CH2:Value"  # same terminal, other symbol
NEIGHBOUR_STATUS = "ETH1:RIO21:MOD22:CH1:Overrange"  # STEADY's struct
COE = "ETH1:RIO21:MOD22:C8000:CoeOffset"  # Term 22's CoE 0x8000:11, pinned by alias
COE_PATH = (
    "Device 1 (EtherCAT)^Term 21 (EK1122)^Term 22 (EL3104)"
    "^Coe ai_settings_8000_user_scale_offset"
)
LOSS_LIMIT_S = 8.0
"""A fault to its PVs INVALID (a lost target, a slave out of OP, a lost link,
PDOs gone in an online change), a generous bound of the behaviour on a busy
host: the targets (1 s for a lost target, 2.5 s for a slave's state or link,
2 s for PDOs gone) are `fastcs-ethercat bench --only faults`'s figures."""
RECOVERY_LIMIT_S = 15.0
"""The fault gone to PVs valid and updating again, a generous bound: the
targets (5 s; 3 s for a slave back in OP) are the benchmark's."""


@dataclass
class Watch:
    """Every PVA update of some PVs: (monotonic time, severity, value, alarm
    message); the IOC's PVA alarm message starts with the CA status name."""

    updates: dict[str, list[tuple[float, int, Any, str]]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def callback(self, name: str) -> Any:
        def on_update(value: Any) -> None:
            if isinstance(value, Exception):
                return
            message = str(value.raw.alarm.message)
            with self.lock:
                self.updates.setdefault(name, []).append(
                    (time.monotonic(), int(value.severity), value.raw.value, message)
                )

        return on_update

    def first_update(
        self, name: str, since: float, severity: int
    ) -> tuple[float, str] | None:
        """(seconds from `since`, alarm message) of the first update with
        `severity`."""
        with self.lock:
            for stamp, sev, _, message in self.updates.get(name, []):
                if stamp >= since and sev == severity:
                    return stamp - since, message
        return None

    def first(self, name: str, since: float, severity: int) -> float | None:
        """Seconds from `since` to the first update with `severity`."""
        found = self.first_update(name, since, severity)
        return None if found is None else found[0]

    def severity(self, name: str) -> int:
        with self.lock:
            return self.updates[name][-1][1]

    def value(self, name: str) -> Any:
        with self.lock:
            return self.updates[name][-1][2]

    def count_since(self, name: str, since: float) -> int:
        with self.lock:
            return sum(1 for stamp, *_ in self.updates.get(name, []) if stamp >= since)


@dataclass
class Rig:
    sim: SimProcess
    ioc: IocProcess
    watch: Watch
    figures: dict[str, float]
    replaced: list[SimProcess] = field(default_factory=list)
    """Simulators started in place of the first one (stopped at the end)."""
    work: Path | None = None

    def pv(self, name: str) -> str:
        return self.ioc.pv(name)

    def root(self, name: str) -> str:
        pv = self.pv(name)
        return caget(self.ioc, "-S", pv).get(pv, "")

    def wait_invalid(
        self, name: str, since: float, timeout: float = 10, status: str = ""
    ) -> float:
        """Seconds from `since` until `name` went INVALID (with alarm status
        `status`, e.g. "COMM", if given)."""
        found = wait_for(
            lambda: self.watch.first_update(self.pv(name), since, INVALID), timeout
        )
        assert found is not None, f"{name} never went INVALID"
        delay, message = found
        assert message.startswith(status), (name, message)
        return delay

    def wait_valid(self, name: str, since: float, timeout: float = 15) -> float:
        """Seconds from `since` until `name` is valid and updating again."""

        pv = self.pv(name)

        def valid() -> float | None:
            lost = self.watch.first(pv, since, INVALID)
            start = since + (lost or 0.0)  # valid again after the alarm, if any
            back = self.watch.first(pv, start, 0)
            if back is None or self.watch.severity(pv) != 0:
                return None
            return back + start - since

        found = wait_for(valid, timeout)
        assert found is not None, f"{name} never came back"
        return found

    def all_back(self, timeout: float = 20) -> bool:
        return bool(
            wait_for(
                lambda: (
                    self.root("ConnectionState") == "CONNECTED"
                    and self.root("InvalidPvs") == "0"
                ),
                timeout,
            )
        )


def _config(work: Path, sim: SimProcess, prefix: str) -> Path:
    return write_ioc_config(
        work,
        prefix,
        sim.pyads_ip,
        sim.net_id,
        poll_rate_hz=20,
        terminal_dirs=[str(terminals_with_coe(work / "terminals"))],
        pv_aliases={COE_PATH: "CoeOffset"},
    )


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    work = tmp_path_factory.mktemp("faults")

    def config(sim: SimProcess, prefix: str) -> Path:
        return _config(work, sim, prefix)

    with served_ioc("FLT", DEMO_CHAIN, config) as (sim, ioc):
        watch = Watch()
        with ioc.p4p_context() as context:
            names = [
                ioc.pv(name) for name in (SINE, STEADY, NEIGHBOUR, NEIGHBOUR_STATUS)
            ] + [ioc.pv(COE + "_RBV")]
            subscriptions = [
                context.monitor(name, watch.callback(name)) for name in names
            ]
            rig = Rig(sim, ioc, watch, {}, work=work)
            assert wait_for(lambda: rig.root("Connected") == "True", 30)
            try:
                yield rig
            finally:
                for subscription in subscriptions:
                    subscription.close()
                for replaced in rig.replaced:
                    replaced.__exit__(None, None, None)
        print(
            "\nfault figures (s): "
            + ", ".join(f"{k}={v:.2f}" for k, v in rig.figures.items())
        )


@pytest.fixture(autouse=True)
def clean(request: pytest.FixtureRequest) -> Iterator[None]:
    """After a test with the rig: no fault left, every PV served again."""
    yield
    if "rig" not in request.fixturenames:
        return
    rig: Rig = request.getfixturevalue("rig")
    rig.sim.clear_faults()
    assert rig.all_back(), (rig.root("ConnectionState"), rig.root("InvalidPvs"))


def _outage(rig: Rig, name: str, kind: str, hold: float, **params: Any) -> None:
    """Inject `kind`, expect every PV INVALID, clear after `hold`, expect all back."""
    pid = rig.ioc.child.pid
    reconnects = int(rig.root("Reconnects"))
    start = time.monotonic()
    rig.sim.add_fault(kind, **params)
    loss = rig.wait_invalid(SINE, start, status="COMM")
    steady_loss = rig.wait_invalid(STEADY, start, status="COMM")
    time.sleep(max(0.0, hold - (time.monotonic() - start)))
    cleared = time.monotonic()
    rig.sim.clear_faults()
    back = rig.wait_valid(SINE, cleared)
    rig.figures[f"{name}_loss"] = max(loss, steady_loss)
    rig.figures[f"{name}_recovery"] = back
    # The failed poll alarms the PVs at once; the supervisor, woken by it,
    # declares the loss and reconnects (too quickly for a caget to catch
    # every state in between): it counts a reconnect.
    reconnected = wait_for(lambda: int(rig.root("Reconnects")) > reconnects, 5)

    assert max(loss, steady_loss) < LOSS_LIMIT_S
    assert reconnected
    assert back < RECOVERY_LIMIT_S
    assert rig.ioc.child.returncode is None and rig.ioc.child.pid == pid


@pytest.mark.e2e
def test_dropped_connections_reconnect(rig: Rig) -> None:
    _outage(rig, "drop", "drop", 0.0)
    counted = wait_for(lambda: int(rig.root("Reconnects")) >= 1, 5)

    assert counted
    assert 0 < float(rig.root("LastRecovery")) < RECOVERY_LIMIT_S


@pytest.mark.e2e
def test_refused_connections_back_after_refusal(rig: Rig) -> None:
    start = time.monotonic()
    rig.sim.add_fault("refuse", seconds=3)
    loss = rig.wait_invalid(SINE, start, status="COMM")
    disconnected = wait_for(lambda: rig.root("ConnectionState") == "DISCONNECTED", 2)
    error = rig.root("LastError")
    back = rig.wait_valid(SINE, start + 3)
    rig.figures["refuse3_loss"] = loss
    rig.figures["refuse3_recovery_after_refusal"] = back

    assert loss < LOSS_LIMIT_S
    assert disconnected
    assert error
    assert back < RECOVERY_LIMIT_S


@pytest.mark.e2e
def test_stalled_target(rig: Rig) -> None:
    _outage(rig, "stall", "stall", 2.0)


@pytest.mark.e2e
def test_runtime_stop(rig: Rig) -> None:
    start = time.monotonic()
    rig.sim.add_fault("stop")
    loss = rig.wait_invalid(STEADY, start)
    stopped = wait_for(lambda: rig.root("ConnectionState") == "STOPPED", 5)
    cleared = time.monotonic()
    rig.sim.clear_faults()
    back = rig.wait_valid(SINE, cleared)
    rig.figures["stop_loss"] = loss
    rig.figures["stop_recovery"] = back

    assert loss < LOSS_LIMIT_S
    assert stopped
    assert back < RECOVERY_LIMIT_S


@pytest.mark.e2e
def test_sum_read_error_alarms_and_recovers(rig: Rig) -> None:
    """The sum read fails as a whole (0x708, device busy): every polled PV
    alarms until it reads again. (0x701 would say the target has no sum
    reads: the IOC would read them one by one instead.)"""
    start = time.monotonic()
    rig.sim.add_fault("error", code=1800, group=0xF080)
    loss = rig.wait_invalid(SINE, start)
    cleared = time.monotonic()
    rig.sim.clear_faults()
    back = rig.wait_valid(SINE, cleared)
    rig.figures["sum_error_alarm"] = loss
    rig.figures["sum_error_recovery"] = back

    assert loss < LOSS_LIMIT_S
    assert back < RECOVERY_LIMIT_S


@pytest.mark.e2e
def test_item_error_alarms_only_the_failing_symbols_pvs(rig: Rig) -> None:
    """TwinCAT fails one item of a sum read: the PVs of that symbol go
    INVALID (READ), the terminal's other symbols and every other PV keep
    updating; when the item reads again the PVs are valid and follow.

    An item is one symbol of the table read by its handle: a member that
    cannot be read fails its whole structure (`Status` with `Value`)."""
    steady, neighbour = rig.pv(STEADY), rig.pv(NEIGHBOUR)
    start = time.monotonic()
    rig.sim.add_fault("error", code=0x707, symbols=[STEADY_SYMBOL])
    loss = rig.wait_invalid(STEADY, start, status="READ")
    rig.sim.set_symbol(STEADY_SYMBOL, 5151)  # must not reach the PV now
    during = time.monotonic()
    time.sleep(1.0)
    updates = {
        name: rig.watch.count_since(rig.pv(name), during) for name in (SINE, NEIGHBOUR)
    }
    alarms = rig.ioc.tool("caget", "-a", steady, neighbour)
    severities = {
        name: rig.watch.severity(rig.pv(name))
        for name in (SINE, NEIGHBOUR, NEIGHBOUR_STATUS)
    }
    held = caget(rig.ioc, steady)[steady]
    cleared = time.monotonic()
    rig.sim.clear_faults()
    rig.sim.set_symbol(STEADY_SYMBOL, 6161)
    back = rig.wait_valid(STEADY, cleared)
    follows = wait_for(lambda: caget(rig.ioc, steady).get(steady) == "6161", 5)
    rig.figures["item_error_alarm"] = loss
    rig.figures["item_error_back"] = back

    assert loss < LOSS_LIMIT_S
    assert updates[SINE] >= 5 and updates[NEIGHBOUR] >= 5, updates
    assert severities == {SINE: 0, NEIGHBOUR: 0, NEIGHBOUR_STATUS: INVALID}
    steady_line = next(line for line in alarms.splitlines() if steady in line)
    assert "INVALID" in steady_line and "READ" in steady_line, alarms
    neighbour_line = next(line for line in alarms.splitlines() if neighbour in line)
    assert "INVALID" not in neighbour_line, alarms
    assert held != "5151"
    assert back < RECOVERY_LIMIT_S
    assert follows
    assert wait_for(lambda: rig.root("InvalidPvs") == "0", 5)  # a 1 s scan


@pytest.mark.e2e
def test_coe_values_go_invalid_on_loss_and_are_read_again(rig: Rig) -> None:
    """A CoE PV is a PV of the target like the others: INVALID with COMM on
    a loss; after the reconnect it shows what the slave holds now (read
    again), not the value from before. A restarted target has its defaults
    back, so a value set before the outage must not survive it."""
    coe, readback = rig.pv(COE), rig.pv(COE + "_RBV")
    rig.ioc.tool("caput", coe, "77")
    written = wait_for(lambda: caget(rig.ioc, readback).get(readback) == "77", 10)
    pid = rig.ioc.child.pid

    old = rig.sim
    stopped = time.monotonic()
    old.stop()
    try:
        loss = rig.wait_invalid(COE + "_RBV", stopped, status="COMM")
        alarm = rig.ioc.tool("caget", "-a", readback)
    finally:
        _start_in_place_of(rig, old, DEMO_CHAIN)
    started = time.monotonic()
    back = rig.wait_valid(COE + "_RBV", started)
    value = rig.watch.value(readback)
    rig.figures["coe_loss"] = loss
    rig.figures["coe_read_again"] = back

    assert written
    assert loss < LOSS_LIMIT_S
    assert "INVALID" in alarm and "COMM" in alarm, alarm
    assert value == 0  # the restarted slave's default, read again
    assert back < RECOVERY_LIMIT_S
    assert rig.ioc.child.pid == pid and rig.ioc.child.returncode is None


@pytest.mark.e2e
def test_slave_in_preop_alarms_only_its_points(rig: Rig) -> None:
    start = time.monotonic()
    rig.sim.add_fault("slave_state", state="PREOP", name="Term 5 (EL3104)")
    loss = rig.wait_invalid(SINE, start)
    rig.sim.set_symbol(STEADY_SYMBOL, 4242)
    steady = rig.pv(STEADY)
    follows = wait_for(lambda: caget(rig.ioc, steady).get(steady) == "4242", 10)
    steady_severity = rig.watch.severity(steady)
    state = caget(rig.ioc, "-S", rig.pv("ETH1:RIO1:MOD5:AlState"))
    cleared = time.monotonic()
    rig.sim.clear_faults()
    back = rig.wait_valid(SINE, cleared)
    rig.figures["preop_alarm"] = loss
    rig.figures["preop_recovery"] = back

    assert loss < LOSS_LIMIT_S
    assert follows and steady_severity == 0
    assert state[rig.pv("ETH1:RIO1:MOD5:AlState")] == "PREOP"
    assert back < RECOVERY_LIMIT_S


@pytest.mark.e2e
def test_lost_link_alarms_only_that_slave(rig: Rig) -> None:
    start = time.monotonic()
    rig.sim.add_fault("link_lost", name="Term 22 (EL3104)")
    loss = rig.wait_invalid(STEADY, start)
    lost = time.monotonic()
    time.sleep(1.0)
    sine_moving = rig.watch.count_since(rig.pv(SINE), lost)
    sine_severity = rig.watch.severity(rig.pv(SINE))
    steady_severity = rig.watch.severity(rig.pv(STEADY))
    rig.figures["link_lost_alarm"] = loss

    assert loss < LOSS_LIMIT_S
    assert sine_moving > 0  # the other slave's values keep coming, valid
    assert sine_severity == 0
    assert steady_severity == INVALID  # and the lost one stays in alarm


@pytest.mark.e2e
def test_lost_link_is_judged_per_port(rig: Rig) -> None:
    """Term 6 loses its link: Term 5 before it reports a missing link on its
    port B (0x24), which is Term 6's fault, not its own: Term 5's values stay
    valid and its LinkOk true; only Term 6 alarms."""
    start = time.monotonic()
    rig.sim.add_fault("link_lost", name="Term 6 (EL2024)")
    lost = rig.pv("ETH1:RIO1:MOD6:CH1:Output_RBV")
    alarmed = wait_for(lambda: "INVALID" in rig.ioc.tool("caget", "-a", lost), 5)
    before = [rig.pv(f"ETH1:RIO1:MOD5:{leaf}") for leaf in ("LinkOk", "LinkState")]
    own = [rig.pv(f"ETH1:RIO1:MOD6:{leaf}") for leaf in ("LinkOk", "LinkState")]
    diagnostics = wait_for(
        lambda: (found := caget(rig.ioc, *before, *own))[own[1]] != "0" and found, 5
    )
    time.sleep(0.5)

    assert alarmed
    assert diagnostics[before[0]] == "True" and diagnostics[before[1]] == "36"
    assert diagnostics[own[0]] == "False" and diagnostics[own[1]] == "1"
    assert rig.watch.first(rig.pv(SINE), start, INVALID) is None
    assert rig.watch.severity(rig.pv(SINE)) == 0


@pytest.mark.e2e
def test_online_change_resolves_again_without_restart(rig: Rig) -> None:
    pid = rig.ioc.child.pid
    version = int(rig.root("SymbolVersion"))
    start = time.monotonic()
    rig.sim.add_fault("online_change")
    bumped = wait_for(lambda: int(rig.root("SymbolVersion")) != version, 10)
    resolved = time.monotonic() - start
    rig.sim.set_symbol(STEADY_SYMBOL, -1717)
    steady = rig.pv(STEADY)
    follows = wait_for(lambda: caget(rig.ioc, steady).get(steady) == "-1717", 10)
    rig.figures["online_change_resolved"] = resolved

    assert bumped and follows
    assert rig.ioc.child.pid == pid and rig.ioc.child.returncode is None


@pytest.mark.e2e
def test_writes_are_checked_rejected_while_away_and_alarm_on_error(
    rig: Rig,
) -> None:
    ioc = rig.ioc
    pv = rig.pv("ETH1:RIO21:MOD24:CH3:AnalogOutput")
    ioc.tool("caput", pv, "321")
    assert wait_for(lambda: rig.sim.get_symbol(OUTPUT) == 321, 10)

    rig.sim.add_fault("refuse", seconds=3)
    assert wait_for(lambda: rig.root("ConnectionState") != "CONNECTED", 5)
    ioc.tool("caput", pv, "654")
    assert rig.all_back()
    time.sleep(1.0)
    kept = rig.sim.get_symbol(OUTPUT)

    # writes go by handle: group 0xF005 (value by handle) on the device port
    rig.sim.add_fault("error", code=1793, group=0xF005)
    ioc.tool("caput", pv, "987")
    alarm = ioc.tool("caget", "-a", pv)
    rig.sim.clear_faults()
    readback = caget(ioc, pv + "_RBV")[pv + "_RBV"]

    assert kept == 321  # not queued, not replayed after the reconnect
    assert "WRITE" in alarm and "INVALID" in alarm, alarm
    assert rig.sim.get_symbol(OUTPUT) == 321
    assert readback == "321"


@pytest.mark.e2e
def test_online_change_of_pdo_groups_alarms_only_what_went(rig: Rig) -> None:
    start = time.monotonic()
    rig.sim.add_fault("online_change", pdo_groups={"Term 5 (EL3104)": "Standard"})
    try:
        gone = rig.wait_invalid(SINE, start)
        changes = wait_for(lambda: rig.root("ChainChanges"), 5)
        rig.sim.set_symbol(STEADY_SYMBOL, 2468)
        steady = rig.pv(STEADY)
        follows = wait_for(lambda: caget(rig.ioc, steady).get(steady) == "2468", 10)
        steady_severity = rig.watch.severity(steady)
    finally:
        again = time.monotonic()
        rig.sim.add_fault("online_change", pdo_groups={"Term 5 (EL3104)": "Compact"})
    back = rig.wait_valid(SINE, again)
    cleared = wait_for(lambda: rig.root("ChainChanges") == "", 5)
    rig.figures["pdo_change_alarm"] = gone
    rig.figures["pdo_change_back"] = back

    assert gone < LOSS_LIMIT_S
    assert "served points gone" in changes
    assert follows and steady_severity == 0
    assert back < RECOVERY_LIMIT_S
    assert cleared


# -- the parts, without a target ----------------------------------------------


def _point(type_name: str, kind: PointKind = PointKind.SCALAR, **extra: Any) -> Point:
    return Point(
        key=f"m/s/{type_name}",
        symbol=f"Term 9 (X).{type_name}",
        attribute=type_name.lower(),
        type_name=type_name,
        kind=kind,
        index_group=0xF020,
        index_offset=0,
        byte_size=2,
        writable=True,
        **extra,
    )


@pytest.mark.parametrize(
    ("point", "value"),
    [
        (_point("INT"), 32768),
        (_point("INT"), -32769),
        (_point("UINT"), -1),
        (_point("USINT"), 256),
        (_point("DINT"), 1.5),
        (_point("UDINT"), "7"),
        (_point("REAL"), float("nan")),
        (_point("REAL"), 1e39),
        (_point("BOOL"), 2),
        (_point("BITS", PointKind.BITS, bit_size=2), 4),
        (_point("INT", PointKind.ARRAY, length=3), [1, 2]),
        (_point("INT", PointKind.ARRAY, length=2), [1, 40000]),
    ],
)
def test_writes_out_of_type_or_range_never_reach_ads(point: Point, value: Any) -> None:
    with pytest.raises(ValueError):
        check_write(point, value)


@pytest.mark.parametrize(
    ("point", "value"),
    [
        (_point("INT"), -32768),
        (_point("UDINT"), 2**32 - 1),
        (_point("LREAL"), 1e300),
        (_point("BOOL"), True),
        (_point("BITS", PointKind.BITS, bit_size=2), 3),
        (_point("INT", PointKind.ARRAY, length=2), [1, -2]),
    ],
)
def test_writes_within_type_and_range_pass(point: Point, value: Any) -> None:
    check_write(point, value)


def _plan(*slaves: tuple[int, str, int]) -> SystemPlan:
    master = MasterPlan(1, "Device 1 (EtherCAT)", "5.1.2.3.2.1", 27905)
    master.terminals = [
        TerminalPlan(
            SlaveInfo(address, name, SlaveIdentity(2, product, 0x100000)), name
        )
        for address, name, product in slaves
    ]
    return SystemPlan("5.1.2.3.1.1", "sim", "3.1", 1, [master])


def test_chain_changes_name_what_went_came_and_changed() -> None:
    before = _plan((1001, "Term 1 (EK1100)", 1), (1002, "Term 2 (EL3104)", 2))
    after = _plan((1001, "Term 1 (EK1100)", 1), (1002, "Term 2 (EL3102)", 3))
    after.masters[0].terminals.append(
        TerminalPlan(
            SlaveInfo(1003, "Term 3 (EL2024)", SlaveIdentity(2, 4, 0x100000)), None
        )
    )

    changes = chain_changes(before, after)

    assert chain_changes(before, before) == []
    assert len(changes) == 2
    assert "1002" in changes[0] and "EL3104" in changes[0] and "EL3102" in changes[0]
    assert "1003 new" in changes[1]


async def test_health_holds_values_until_every_reason_is_gone() -> None:
    health = Health()
    attr = AttrR(Int())
    other = AttrR(Int())
    health.mark_invalid([attr, other], COMM, Status.COMM, "gone")
    health.mark_invalid([attr], "slave", Status.STATE, "PREOP")
    await health.post(attr, 5)  # fresh: COMM goes, the slave reason stays
    await health.post(other, 6)
    held = attr.get()
    reasons = health.reasons(attr)
    await health.mark_ok([attr], "slave")

    assert held == 0 and reasons == ["slave"]
    assert attr.get() == 5 and other.get() == 6
    assert not health.is_invalid(attr) and health.invalid_count == 0


def _restart_sim(rig: Rig, chain: Path) -> float:
    """Stop the simulator and start one of `chain` on the same ports."""
    old = rig.sim
    stopped = time.monotonic()  # the IOC may notice while the old one stops
    old.stop()
    _start_in_place_of(rig, old, chain)
    return stopped


def _start_in_place_of(rig: Rig, old: SimProcess, chain: Path) -> None:
    """A simulator of `chain` on the ports of the stopped `old` one."""
    new = SimProcess(
        chain=chain,
        terminals=TERMINALS_DIR,
        port=old.tcp_port,
        udp_port=old.udp_port,
        env=rig.ioc.env,
    )
    rig.replaced.append(new)
    new.start()
    rig.sim = new


@pytest.mark.e2e
def test_target_restarted_with_another_chain_keeps_unchanged_terminals(
    rig: Rig,
) -> None:
    assert rig.work is not None
    changed = rig.work / "changed-chain.yaml"
    text = DEMO_CHAIN.read_text(encoding="utf-8")
    assert "  - type: EL2024                       # Term 20" in text
    changed.write_text(
        text.replace(
            "  - type: EL2024                       # Term 20",
            "  - type: EL1014                       # Term 20",
        ),
        encoding="utf-8",
    )
    term20 = "ETH1:RIO18:MOD20:AlState"
    pid = rig.ioc.child.pid

    stopped = _restart_sim(rig, changed)
    try:
        loss = rig.wait_invalid(SINE, stopped, status="COMM")
        back = rig.wait_valid(SINE, stopped)
        changes = wait_for(lambda: rig.root("ChainChanges"), 5)
        invalid = int(rig.root("InvalidPvs"))
        rig.sim.set_symbol(STEADY_SYMBOL, 1357)
        steady = rig.pv(STEADY)
        follows = wait_for(lambda: caget(rig.ioc, steady).get(steady) == "1357", 10)
        rig.figures["restart_other_chain_back"] = back
    finally:
        restored = _restart_sim(rig, DEMO_CHAIN)
    again = rig.wait_valid(SINE, restored)
    cleared = wait_for(lambda: rig.root("ChainChanges") == "", 10)
    rig.figures["restart_same_chain_back"] = again

    assert loss < LOSS_LIMIT_S
    assert back < RECOVERY_LIMIT_S and again < RECOVERY_LIMIT_S
    assert "1020" in changes and "EL2024" in changes and "EL1014" in changes
    assert invalid > 0  # Term 20's points: gone, in alarm, PVs kept
    assert rig.pv(term20) in caget(rig.ioc, rig.pv(term20))
    assert follows
    assert cleared
    assert rig.ioc.child.pid == pid and rig.ioc.child.returncode is None
