"""The IOC end to end: the simulator with the demo chain, the IOC against it.

One simulator and one IOC subprocess serve every test of this module. The
IOC reads a terminals directory of its own (a copy of `terminals/`) in which
EL3202's YAML is missing, so Term 10 gets the generic controller, and
EL3104's `AI Settings` CoE object (0x8000) is selected, so both EL3104s get
CoE PVs. The simulator models the full chain from the real `terminals/`.

Real clients only: `caget`/`caput`/`pvget`, aioca (in a subprocess), p4p and,
to look behind the IOC, pyads against the simulator and its control API.
"""

from __future__ import annotations

import asyncio
import getpass
import re
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import fastcs_ethercat
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.coe import SlaveCoe
from fastcs_ethercat.ioc.plan import CoePoint
from fastcs_ethercat.runtime import HEARTBEAT_ENV, RUNTIME_ENV
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    BIN,
    IOC_COMMAND,
    START_TIMEOUT,
    IocProcess,
    aioca_get,
    caget,
    ioc_env,
    list_pvs_text,
    new_token,
    start_ioc,
    stop_pid,
    terminals_with_coe,
    wait_for,
    write_ioc_config,
)
from tests.processes import run_python_child

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
MISSING_TYPE = "EL3202"  # Term 10: served by the generic controller
COMPACT = "ETH1:RIO1:MOD5"  # Term 5 (EL3104) in its Compact PDOs
STANDARD = "ETH1:RIO21:MOD22"  # Term 22 (EL3104) in its Standard PDOs


@dataclass(frozen=True)
class Listed:
    """One line of `--list-pvs`."""

    name: str
    access: str
    datatype: str
    source: str


@dataclass
class Demo:
    sim: SimProcess
    ioc: IocProcess
    listings: list[list[str]]
    pvs: dict[str, Listed]
    screens: Path
    figures: dict[str, float]

    def by_source(
        self, source: str, access: str | None = None, datatype: str | None = None
    ) -> str:
        """The PV (the writable one, the one of a type, if asked) of a symbol
        or CoE item (a scaled value has two: `ExactFloat` and its raw `Int`)."""
        names = [
            entry.name
            for entry in self.pvs.values()
            if entry.source == source
            and (access is None or entry.access == access)
            and (datatype is None or entry.datatype == datatype)
        ]
        assert len(names) == 1, f"{source}: {names}"
        return names[0]


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Demo]:
    token = new_token()
    work = tmp_path_factory.mktemp("demo")
    env = {  # as in the image: state in the runtime folder, a heartbeat file
        **ioc_env(token),
        RUNTIME_ENV: str(work / "runtime"),
        HEARTBEAT_ENV: str(work / "heartbeat"),
    }
    prefix = f"TST{token[:6].upper()}"
    screens = work / "screens"
    with SimProcess(chain=DEMO_CHAIN, terminals=TERMINALS_DIR, env=env) as sim:
        config = write_ioc_config(
            work,
            prefix,
            sim.pyads_ip,
            sim.net_id,
            poll_rate_hz=20,
            terminal_dirs=[str(terminals_with_coe(work / "terminals", [MISSING_TYPE]))],
            screens_dir=str(screens),
        )
        figures: dict[str, float] = {}
        started = time.monotonic()
        listings = [list_pvs_text(config, env).splitlines()]
        figures["list_pvs_s"] = time.monotonic() - started
        listings.append(list_pvs_text(config, env).splitlines())
        started = time.monotonic()
        ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
        try:
            ioc.wait_for_line("ioc ready", START_TIMEOUT)
            figures["ready_s"] = time.monotonic() - started
            first = ioc.pv("Connected")
            assert wait_for(lambda: caget(ioc, first).get(first) == "True", 30)
            figures["polling_s"] = time.monotonic() - started
            pvs = {}
            for line in listings[0]:
                name, access, datatype, source = line.split(" ", 3)
                pvs[name] = Listed(name, access, datatype, source)
            yield Demo(sim, ioc, listings, pvs, screens, figures)
        finally:
            ioc.stop()
            if ioc.child.returncode is None:
                stop_pid(ioc.child.pid)


@pytest.mark.perf
def test_start_figures(demo: Demo) -> None:
    print(
        f"\ndemo chain: --list-pvs {demo.figures['list_pvs_s']:.1f} s, "
        f"ready line {demo.figures['ready_s']:.1f} s, "
        f"polling (Connected=1) {demo.figures['polling_s']:.1f} s, "
        f"{len(demo.pvs)} PVs"
    )
    assert demo.figures["ready_s"] < demo.figures["polling_s"]


def test_pv_list_is_stable_unique_and_fits(demo: Demo) -> None:
    first, second = demo.listings
    names = [line.split(" ", 1)[0] for line in first]

    assert first == second
    assert len(names) == len(set(names)) > 400
    assert all(name.startswith(demo.ioc.prefix + ":") for name in names)
    assert max(len(name) for name in names) <= 60


def test_every_listed_pv_is_served_with_its_type(demo: Demo) -> None:
    expected: dict[str, tuple[type, ...]] = {
        "Bool": (bool, int),
        "Int": (int,),
        "IntegralFloat": (float,),
        "ExactFloat": (float,),
        "String": (str,),
        "Waveform": (np.ndarray, int, float),  # QSRV: an array of one, a scalar
        "Enum": (int, str),
    }
    names = [n for n, e in demo.pvs.items() if e.datatype in expected]
    with demo.ioc.p4p_context() as context:
        values: Any = context.get(names, throw=False, timeout=20)

    wrong = []
    for name, value in zip(names, values, strict=True):
        datatype = demo.pvs[name].datatype
        if isinstance(value, Exception):
            wrong.append((name, repr(value)))
            continue
        raw = value.raw.value
        if datatype in ("Enum", "Bool"):  # bi, mbbi: NTEnum on QSRV
            raw = raw.index
        if not isinstance(raw, expected[datatype]):
            wrong.append((name, f"{datatype}: {type(raw).__name__}"))
    assert wrong == []


def test_compact_and_standard_pdos_of_el3104(demo: Demo) -> None:
    compact = [n for n in demo.pvs if n.startswith(demo.ioc.pv(COMPACT + ":"))]
    standard = [n for n in demo.pvs if n.startswith(demo.ioc.pv(STANDARD + ":"))]
    values = caget(demo.ioc, *(demo.ioc.pv(f"{COMPACT}:CH{k}:Value") for k in (1, 2)))

    assert {demo.ioc.pv(f"{COMPACT}:CH{k}:Value") for k in range(1, 5)} <= set(compact)
    assert not any(name.endswith(":Underrange") for name in compact)
    assert demo.ioc.pv(f"{STANDARD}:CH1:Value") in standard
    assert demo.ioc.pv(f"{STANDARD}:CH1:Underrange") in standard
    assert all(-10.001 <= float(value) <= 10.0 for value in values.values())  # V
    assert len(values) == 2


def test_values_follow_the_simulator(demo: Demo) -> None:
    symbol = "Term 22 (EL3104).AI Standard Channel 1.Value"
    pv = demo.by_source(symbol, datatype="Int")  # the raw count
    sine = demo.ioc.pv(f"{COMPACT}:CH1:Value")
    demo.sim.set_symbol(symbol, -4321)
    first = caget(demo.ioc, sine)[sine]

    followed = wait_for(lambda: caget(demo.ioc, pv).get(pv) == "-4321", 10)
    demo.sim.set_symbol(symbol, 1234)
    followed_again = wait_for(lambda: caget(demo.ioc, pv).get(pv) == "1234", 10)
    moved = wait_for(lambda: caget(demo.ioc, sine)[sine] != first, 10)

    assert followed and followed_again and moved


def test_caput_reaches_the_process_image_and_the_readback_follows(
    demo: Demo,
) -> None:
    symbol = "Term 24 (EP4374-0002).AO Outputs Channel 3"
    pv = demo.by_source(symbol, access="rw")
    demo.ioc.tool("caput", pv, "1234")

    in_image = wait_for(lambda: demo.sim.get_symbol(symbol) == 1234, 10)
    readback = wait_for(lambda: aioca_get(demo.ioc, [pv + "_RBV"]), 10)
    demo.ioc.tool("caput", pv, "99999")  # beyond INT: CA clamps to DRVH
    clamped = wait_for(lambda: demo.sim.get_symbol(symbol) == 32767, 10)

    assert in_image
    assert readback == {pv + "_RBV": "1234"}
    assert clamped


def _put_lines(demo: Demo, tool: str, pv: str, value: str) -> list[str]:
    """Every line the IOC says that names `pv`, from the put by `tool` on
    (at --log-level info) until a second would have come."""
    demo.ioc.unread()
    since = len(demo.ioc.output)
    said = demo.ioc.tool(tool, pv, value)
    demo.ioc.wait_for_line(rf"{re.escape(pv)}\.VAL \S+ -> {value}$", 10)
    time.sleep(1)  # a second line would be here by now
    demo.ioc.unread()
    named = [line.strip() for line in demo.ioc.output[since:] if pv in line]
    assert named, said
    return named


@pytest.mark.parametrize(
    ("tool", "channel", "value"), [("caput", 4, "321"), ("pvput", 3, "123")]
)
def test_a_put_gives_one_audit_line_naming_the_client(
    demo: Demo, tool: str, channel: int, value: str
) -> None:
    """One line: the audit's (FastCS's own `PV put` line is left to debug),
    naming the client's user and host: CA's host name, or on PV Access
    (QSRV) the client's address, which QSRV gives asTrapWrite."""
    symbol = f"Term 24 (EP4374-0002).AO Outputs Channel {channel}"
    pv = demo.by_source(symbol, access="rw")
    before = caget(demo.ioc, pv)[pv]
    [line] = _put_lines(demo, tool, pv, value)
    found = re.fullmatch(rf"(\S+)@(\S+) {re.escape(pv)}\.VAL (\S+) -> {value}", line)
    assert found is not None, line
    user, host, old = found.groups()

    assert user == getpass.getuser()
    assert host == "127.0.0.1" if tool == "pvput" else host  # loopback here
    assert float(old) == float(before)


def test_coe_write_reaches_the_simulated_slave(demo: Demo) -> None:
    pv = _coe_pv(demo)
    demo.ioc.tool("caput", "-S", pv, "Absolute MSB sign")
    master_net_id = caget(demo.ioc, "-S", demo.ioc.pv("ETH1:NetId"))[
        demo.ioc.pv("ETH1:NetId")
    ]
    point = CoePoint("presentation", 0x8000, 0x02, "USINT", 3, True)

    async def read_sdo() -> Any:
        async with ClientPool(demo.sim.host, demo.sim.tcp_port) as pool:
            return await SlaveCoe(pool, master_net_id, 1022).read(point)

    value = wait_for(lambda: asyncio.run(read_sdo()) == 2, 10)
    readback = caget(demo.ioc, "-S", pv + "_RBV")[pv + "_RBV"]

    assert value
    assert readback == "Absolute MSB sign"


def _coe_pv(demo: Demo) -> str:
    names = [
        entry.name
        for entry in demo.pvs.values()
        if entry.source == "CoE:8000:02"
        and entry.access == "rw"
        and entry.name.startswith(demo.ioc.pv(STANDARD + ":"))
    ]
    assert len(names) == 1, names
    return names[0]


def test_unknown_terminal_gets_the_generic_controller(demo: Demo) -> None:
    generic = demo.ioc.pv("ETH1:RIO1:MOD10")
    served = [n for n, e in demo.pvs.items() if n.startswith(generic + ":")]
    sources = {demo.pvs[n].source for n in served}
    values = caget(demo.ioc, "-S", f"{generic}:Type", f"{generic}:AlState")

    assert any(source.startswith("Term 10 (EL3202).") for source in sources)
    assert values[f"{generic}:Type"] == "EL3202"  # as the master reports it
    assert values[f"{generic}:AlState"] == "OP"


def test_master_and_root_diagnostics(demo: Demo) -> None:
    p = demo.ioc.pv
    names = [p("ETH1:SlaveCount"), p("ETH1:ExpectedSlaves"), p("PollRate")]
    names += [p("AdsRequestRate"), p("Terminals"), p("PollErrors")]
    values = wait_for(
        lambda: (v := caget(demo.ioc, *names)) and float(v[p("PollRate")]) > 5 and v,
        10,
    )

    assert values[p("ETH1:SlaveCount")] == "24"
    assert values[p("ETH1:ExpectedSlaves")] == "24"
    assert float(values[p("AdsRequestRate")]) > 5
    assert values[p("Terminals")] == "24"


def test_pvget_pvi_and_screens(demo: Demo) -> None:
    terminal = demo.ioc.pv(COMPACT)
    pvi = demo.ioc.tool("pvget", terminal + ":PVI")
    channel_pvi = demo.ioc.tool("pvget", terminal + ":CH1:PVI")
    root_pvi = demo.ioc.tool("pvget", demo.ioc.pv("PVI"))
    screen = demo.screens / "ETH1_RIO1_MOD5.bob"

    assert f"string d {terminal}:CH1:PVI" in pvi
    assert f"string r {terminal}:AlState" in pvi
    assert f"string r {terminal}:CH1:Value" in channel_pvi
    assert f"string d {demo.ioc.pv('ETH1:PVI')}" in root_pvi
    assert (demo.screens / "index.bob").is_file()
    assert f"{terminal}:CH1:Value" in screen.read_text()
    assert f"{terminal}:AlState" in (demo.screens / "ETH1.bob").read_text()


def test_faults_show_and_polling_recovers(demo: Demo) -> None:
    p = demo.ioc.pv
    symbol = "Term 22 (EL3104).AI Standard Channel 2.Value"
    pv = demo.by_source(symbol, datatype="Int")
    state = p("ETH1:RIO1:MOD6:AlState")
    try:
        demo.sim.add_fault("error", code=1800, group=0xF080)  # sum reads fail (busy)
        demo.sim.add_fault("slave_state", state="SAFEOP", name="Term 6 (EL2024)")
        errors = wait_for(lambda: _number(demo, "PollErrors") > 0, 10)
        safeop = wait_for(lambda: caget(demo.ioc, "-S", state)[state] == "SAFEOP", 10)
        major = caget(demo.ioc, "-a", state)[state].split()[-2:]
    finally:
        demo.sim.clear_faults()
    demo.sim.set_symbol(symbol, 777)
    recovered = wait_for(lambda: caget(demo.ioc, pv).get(pv) == "777", 10)
    back_in_op = wait_for(lambda: caget(demo.ioc, "-S", state)[state] == "OP", 10)

    assert errors and safeop
    assert major == ["STATE", "MAJOR"]  # not in OP: MAJOR
    assert recovered and back_in_op
    assert caget(demo.ioc, "-a", state)[state].split()[-1] == "OP"  # no alarm


def _number(demo: Demo, name: str) -> float:
    pv = demo.ioc.pv(name)
    return float(caget(demo.ioc, pv).get(pv, "nan"))


_MONITOR_STAMPS = """
import asyncio, sys, aioca
async def main(seconds, names):
    events = []
    def seen(value, index):
        events.append((names[index], value.raw_stamp))
    subs = aioca.camonitor(names, seen, format=aioca.FORMAT_TIME, all_updates=True)
    await asyncio.sleep(seconds)
    for sub in subs:
        sub.close()
    for name, (seconds_, nanoseconds) in events:
        print(name, seconds_, nanoseconds)
asyncio.run(main(float(sys.argv[1]), sys.argv[2:]))
"""


def _ca_stamps(demo: Demo, names: list[str], seconds: float) -> list[tuple[str, int]]:
    """(PV, timestamp in ns) of every CA monitor event over `seconds`."""
    done = run_python_child(
        _MONITOR_STAMPS, str(seconds), *names, env=demo.ioc.env, timeout=60
    )
    events = []
    for line in done.stdout.splitlines():
        name, seconds_, nanoseconds = line.split()
        events.append((name, int(seconds_) * 10**9 + int(nanoseconds)))
    return events


def test_values_of_one_poll_cycle_are_stamped_together(demo: Demo) -> None:
    """A value's time is its record's processing (TSE 0), the same on CA and
    PVA; the values one poll cycle changes are processed together, so their
    times gather in one burst a cycle, milliseconds wide."""
    names = [
        entry.name
        for entry in demo.pvs.values()
        if entry.access == "r"
        and entry.datatype in ("Int", "ExactFloat", "IntegralFloat")
        and "(" in entry.source  # a TwinCAT symbol of a terminal
    ][:80]
    seconds, rate = 2.0, 20
    pva_stamps: dict[str, set[int]] = {}
    with demo.ioc.p4p_context() as context:

        def on_value(name: str, value: Any) -> None:
            stamp = value.raw.timeStamp
            pva_stamps.setdefault(name, set()).add(
                stamp.secondsPastEpoch * 10**9 + stamp.nanoseconds
            )

        subscriptions = [
            context.monitor(name, lambda v, n=name: on_value(n, v)) for name in names
        ]
        try:
            events = _ca_stamps(demo, names, seconds)
        finally:
            for subscription in subscriptions:
                subscription.close()

    by_pv: dict[str, set[int]] = {}
    for name, stamp in events:
        by_pv.setdefault(name, set()).add(stamp)
    changing = {name: s for name, s in by_pv.items() if len(s) >= 10}
    shared = [pva_stamps.get(name, set()) & stamps for name, stamps in changing.items()]
    bursts = _bursts(sorted(set().union(*changing.values())), gap_ns=10**9 // rate // 2)

    assert len(changing) >= 3, sorted(by_pv)
    assert all(len(stamps) >= 5 for stamps in shared)  # PVA has the same times
    # One burst a cycle (a few more where the machine paused mid-cycle), each
    # holding several values' times, most of them a few milliseconds wide.
    assert len(bursts) <= 1.5 * seconds * rate + 5
    assert sum(map(len, bursts)) >= 2 * len(bursts)
    widths = sorted(burst[-1] - burst[0] for burst in bursts)
    assert widths[len(widths) // 2] < 10 * 10**6, widths


def _bursts(stamps: list[int], gap_ns: int) -> list[list[int]]:
    """Sorted times split where two lie more than `gap_ns` apart."""
    bursts: list[list[int]] = []
    for stamp in stamps:
        if bursts and stamp - bursts[-1][-1] <= gap_ns:
            bursts[-1].append(stamp)
        else:
            bursts.append([stamp])
    return bursts


def test_coe_values_are_read_after_start_and_valid(demo: Demo) -> None:
    """CoE values are read in the background once the IOC serves: each turns
    from INVALID (not read yet) to the slave's value with no alarm."""
    names = [
        entry.name + ("_RBV" if entry.access == "rw" else "")
        for entry in demo.pvs.values()
        if entry.source.startswith("CoE:")
        and entry.name.startswith(demo.ioc.pv(COMPACT + ":"))
    ]

    def severities() -> list[int]:
        with demo.ioc.p4p_context() as context:
            values: Any = context.get(names, throw=False, timeout=10)
        return [
            -1 if isinstance(value, Exception) else value.raw.alarm.severity
            for value in values
        ]

    assert len(names) >= 3
    assert wait_for(lambda: set(severities()) == {0}, 20), severities()


# -- what the values mean: units, severities, descriptions, IOC health ----------

STANDARD_CHANNEL = "Term 22 (EL3104).AI Standard Channel {}"


def test_el3104_value_is_served_in_volts_with_its_raw_count_beside(
    demo: Demo,
) -> None:
    symbol = STANDARD_CHANNEL.format(3) + ".Value"
    volts = demo.by_source(symbol, datatype="ExactFloat")
    raw = demo.by_source(symbol, datatype="Int")
    demo.sim.set_symbol(symbol, 16384)
    followed = wait_for(lambda: caget(demo.ioc, raw).get(raw) == "16384", 10)
    shown = caget(demo.ioc, "-a", volts)[volts].split()  # date, time, value
    control = demo.ioc.tool("caget", "-d", "DBR_CTRL_DOUBLE", volts)
    desc = caget(demo.ioc, "-S", volts + ".DESC")[volts + ".DESC"]
    with demo.ioc.p4p_context() as context:
        value: Any = context.get(volts, timeout=10)
    display = value.raw.display

    assert followed
    assert float(shown[2]) == pytest.approx(16384 * 10 / 32767, abs=1e-4)
    assert re.search(r"^\s*Units:\s+V$", control, re.MULTILINE), control
    assert re.search(r"^\s*Precision:\s+4$", control, re.MULTILINE), control
    assert (display.units, display.precision) == ("V", 4)
    assert desc == "EL3104 AI Standard Ch3 Value"


def test_caput_in_volts_writes_counts(demo: Demo) -> None:
    symbol = "Term 15 (EL4134).AO Output Channel 2"
    pv = demo.by_source(symbol, access="rw")
    demo.ioc.tool("caput", pv, "2.5")

    in_image = wait_for(lambda: demo.sim.get_symbol(symbol) == 8192, 10)
    readback = wait_for(lambda: caget(demo.ioc, pv + "_RBV").get(pv + "_RBV"), 10)

    setpoint = caget(demo.ioc, "-a", pv)[pv].split()  # date, time, value

    assert in_image  # 2.5 V / (10 V / 32767) = 8191.75 -> 8192 counts
    assert float(readback) == pytest.approx(8192 * 10 / 32767, abs=1e-4)
    assert len(setpoint) == 3  # the count written, in volts, with no alarm
    assert float(setpoint[2]) == pytest.approx(8192 * 10 / 32767, abs=1e-4)


_CAMONITOR_LINE = re.compile(
    r"^(?P<name>\S+)\s+(?P<stamp>\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+)\s+(?P<rest>.*)$"
)


def _monitor(demo: Demo, pv: str) -> IocProcess:
    """camonitor of `pv`, its lines in a queue (stop it by its PID alone: it
    carries the IOC's token)."""
    camonitor = [str(BIN / "camonitor"), pv]
    return start_ioc(camonitor, demo.ioc.prefix, demo.ioc.env, demo.ioc.token)


def _next_event(monitor: IocProcess, value: str, timeout: float) -> re.Match[str]:
    """The first monitor event showing `value`."""
    stamp = r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+"
    line = monitor.wait_for_line(rf"^\S+\s+{stamp}\s+{re.escape(value)}(\s|$)", timeout)
    match = _CAMONITOR_LINE.match(line.strip())
    assert match is not None, line
    return match


def test_error_bit_turns_its_status_pv_major_with_the_value(demo: Demo) -> None:
    """The severity rides on the value's own update: the first event that
    shows the Error bit set is already MAJOR, stamped with the poll cycle
    that read it."""
    error = STANDARD_CHANNEL.format(4) + ".Status.Error"
    overrange = STANDARD_CHANNEL.format(4) + ".Status.Overrange"
    error_pv, overrange_pv = demo.by_source(error), demo.by_source(overrange)
    monitor = _monitor(demo, error_pv)
    try:
        _next_event(monitor, "False", 10)
        put_at = time.time()
        demo.sim.set_symbol(error, 1)
        demo.sim.set_symbol(overrange, 1)
        raised = _next_event(monitor, "True", 10)
        while_set = caget(demo.ioc, "-a", error_pv, overrange_pv)
        demo.sim.set_symbol(error, 0)
        demo.sim.set_symbol(overrange, 0)
        cleared = _next_event(monitor, "False", 10)
    finally:
        stop_pid(monitor.child.pid)
        monitor.child.wait(5)
    after = caget(demo.ioc, "-a", error_pv, overrange_pv)
    stamp = time.mktime(time.strptime(raised["stamp"][:19], "%Y-%m-%d %H:%M:%S"))
    stamp += float("0" + raised["stamp"][19:])
    print(f"\nError bit set -> MAJOR event stamped {1000 * (stamp - put_at):.0f} ms "
          f"after the PUT (poll period 50 ms)")  # fmt: skip

    assert raised["rest"].split() == ["True", "STATE", "MAJOR"]
    assert stamp >= put_at - 0.01  # the read that saw it, not an older one
    assert while_set[error_pv].split()[-3:] == ["True", "STATE", "MAJOR"]
    assert while_set[overrange_pv].split()[-3:] == ["True", "STATE", "MINOR"]
    assert cleared["rest"].split() == ["False"]  # back to NO_ALARM with the value
    assert after[error_pv].split()[-1] == "False"
    assert after[overrange_pv].split()[-1] == "False"


def test_diagnostics_are_enums_and_alarms(demo: Demo) -> None:
    p = demo.ioc.pv
    names = [p("ETH1:State"), p("ETH1:RIO21:MOD22:AlState"), p("Connected")]
    names += [p("ETH1:Online"), p("ETH1:RIO21:MOD22:LinkOk"), p("ConnectionState")]
    values = wait_for(
        lambda: (
            (v := caget(demo.ioc, "-a", *names))
            and v[p("Connected")].split()[-1] == "True"
            and v
        ),
        10,
    )

    assert values[p("ETH1:State")].split()[-1] == "OP"  # an mbbi with strings
    assert values[p("ETH1:RIO21:MOD22:AlState")].split()[-1] == "OP"
    assert values[p("ConnectionState")].split()[-1] == "CONNECTED"
    assert all(values[n].split()[-1] in ("OP", "True", "CONNECTED") for n in names)


def test_ioc_health_pvs(demo: Demo) -> None:
    p = demo.ioc.pv
    texts = caget(demo.ioc, "-S", p("Version"), p("StartTime"))
    numbers = [p("Uptime"), p("CpuLoad"), p("MemoryUsed"), p("PollOverruns")]
    first = caget(demo.ioc, *numbers)
    later = wait_for(
        lambda: (
            (v := caget(demo.ioc, *numbers))
            and float(v[p("Uptime")]) > float(first[p("Uptime")])
            and v
        ),
        10,
    )
    started = time.mktime(time.strptime(texts[p("StartTime")], "%Y-%m-%d %H:%M:%S"))

    assert texts[p("Version")] == fastcs_ethercat.__version__
    assert time.time() - 3600 < started <= time.time()
    assert later and float(later[p("Uptime")]) > 0
    assert 0 <= float(later[p("CpuLoad")]) < 400
    assert 20 < float(later[p("MemoryUsed")]) < 4096
    assert int(later[p("PollOverruns")]) >= 0


def test_deviocstats_names_and_the_heartbeat(demo: Demo) -> None:
    p = demo.ioc.pv
    names = [p(n) for n in ("HEARTBEAT", "IOC_CPU_LOAD", "MEM_USED", "START_CNT")]
    first = caget(demo.ioc, *names)
    later = wait_for(
        lambda: (
            (v := caget(demo.ioc, *names))
            and int(v[p("HEARTBEAT")]) > int(first[p("HEARTBEAT")])
            and v
        ),
        10,
    )
    uptime = caget(demo.ioc, "-S", p("UPTIME"))[p("UPTIME")]
    cainfo = demo.ioc.tool("cainfo", p("UPTIME"))
    on_pva = {n: demo.ioc.tool("pvget", p(n)) for n in ("HEARTBEAT", "UPTIME")}
    pid, count, stamp = (demo.screens.parent / "heartbeat").read_text().split()
    start_count = (demo.screens.parent / "runtime" / "ioc" / "start-count").read_text()

    assert later and int(later[p("HEARTBEAT")]) >= 1
    assert re.fullmatch(r"0 days, \d\d:\d\d:\d\d", uptime), uptime
    assert "DBF_CHAR" in cainfo  # a char waveform on CA, not a stringin
    assert re.search(r"\s\d+\s*$", on_pva["HEARTBEAT"]), on_pva  # aliases on PVA
    assert re.search(r'"0 days, \d\d:\d\d:\d\d"', on_pva["UPTIME"]), on_pva
    assert 0 <= float(later[p("IOC_CPU_LOAD")]) <= 100
    assert 20e6 < float(later[p("MEM_USED")]) < 4096e6  # bytes, as devIocStats
    assert int(later[p("START_CNT")]) == int(start_count) == 1
    assert int(pid) == demo.ioc.child.pid and int(count) >= 1
    assert abs(time.time() - float(stamp)) < 10
    assert list((demo.screens.parent / "runtime" / "chains").glob("*.yaml"))
