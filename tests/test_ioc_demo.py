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
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.coe import SlaveCoe
from fastcs_ethercat.ioc.plan import CoePoint
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    START_TIMEOUT,
    IocProcess,
    aioca_get,
    caget,
    ioc_env,
    new_token,
    start_ioc,
    stop_pid,
    terminals_with_coe,
    wait_for,
)

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

    def by_source(self, source: str, access: str | None = None) -> str:
        """The PV (the writable one if asked) of a symbol or CoE item."""
        names = [
            entry.name
            for entry in self.pvs.values()
            if entry.source == source and (access is None or entry.access == access)
        ]
        assert len(names) == 1, f"{source}: {names}"
        return names[0]


def _list_pvs(config: Path, env: dict[str, str]) -> list[str]:
    done = subprocess.run(
        [*IOC_COMMAND, "--config", str(config), "--list-pvs"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.splitlines()


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Demo]:
    token = new_token()
    env = ioc_env(token)
    prefix = f"TST{token[:6].upper()}"
    work = tmp_path_factory.mktemp("demo")
    screens = work / "screens"
    with SimProcess(chain=DEMO_CHAIN, terminals=TERMINALS_DIR, env=env) as sim:
        config = work / "ioc.yaml"
        config.write_text(
            yaml.safe_dump(
                {
                    "prefix": prefix,
                    "target": sim.pyads_ip,
                    "ams_net_id": sim.net_id,
                    "poll_rate_hz": 20,
                    "terminal_dirs": [
                        str(terminals_with_coe(work / "terminals", [MISSING_TYPE]))
                    ],
                    "screens_dir": str(screens),
                }
            )
        )
        figures: dict[str, float] = {}
        started = time.monotonic()
        listings = [_list_pvs(config, env)]
        figures["list_pvs_s"] = time.monotonic() - started
        listings.append(_list_pvs(config, env))
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
            if ioc.process.poll() is None:
                stop_pid(ioc.process.pid)


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
        "Waveform": (np.ndarray,),
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
        if datatype == "Enum":
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
    assert all(-32768 <= int(value) <= 32767 for value in values.values())
    assert len(values) == 2


def test_values_follow_the_simulator(demo: Demo) -> None:
    symbol = "Term 22 (EL3104).AI Standard Channel 1.Value"
    pv = demo.by_source(symbol)
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
    pv = demo.by_source(symbol)
    state = p("ETH1:RIO1:MOD6:AlState")
    try:
        demo.sim.add_fault("error", code=1793, group=0xF080)  # sum reads fail
        demo.sim.add_fault("slave_state", state="SAFEOP", name="Term 6 (EL2024)")
        errors = wait_for(lambda: _number(demo, "PollErrors") > 0, 10)
        safeop = wait_for(lambda: caget(demo.ioc, "-S", state)[state] == "SAFEOP", 10)
    finally:
        demo.sim.clear_faults()
    demo.sim.set_symbol(symbol, 777)
    recovered = wait_for(lambda: caget(demo.ioc, pv).get(pv) == "777", 10)
    back_in_op = wait_for(lambda: caget(demo.ioc, "-S", state)[state] == "OP", 10)

    assert errors and safeop
    assert recovered and back_in_op


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
    done = subprocess.run(
        [sys.executable, "-c", _MONITOR_STAMPS, str(seconds), *names],
        env=demo.ioc.env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    events = []
    for line in done.stdout.splitlines():
        name, seconds_, nanoseconds = line.split()
        events.append((name, int(seconds_) * 10**9 + int(nanoseconds)))
    return events


def test_values_of_one_poll_cycle_carry_one_timestamp(demo: Demo) -> None:
    """Every value a poll cycle changes has that cycle's time, on CA and PVA."""
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
    cycles = set().union(*changing.values())
    shared = [pva_stamps.get(name, set()) & stamps for name, stamps in changing.items()]

    assert len(changing) >= 3, sorted(by_pv)
    # Per-value stamps would give one time per event; one per cycle gives at
    # most one per cycle, whatever the number of PVs.
    assert len(cycles) <= seconds * rate + 5 < sum(map(len, changing.values())) / 2
    assert all(len(stamps) >= 5 for stamps in shared)  # PVA has the same times


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
