"""Alarms on FastCS attributes, end to end in an IOC (CA and PVA serve the
same records).

The IOC (tests/data/alarm_ioc.py) runs in a subprocess on free loopback ports
and takes commands on stdin; real clients read the result: `caget -a`, aioca
with FORMAT_TIME (in a subprocess), `pvget` and p4p. Everything started is
killed by PID, caRepeater included.
"""

from __future__ import annotations

import json
import re
import sys
import time
from collections.abc import Iterator, Sequence
from typing import Any

import pytest
from fastcs.attributes import AttrR
from fastcs.datatypes import Int

from fastcs_ethercat.ioc.alarms import (
    AlarmState,
    Severity,
    Status,
    publish_alarm,
)
from fastcs_ethercat.ioc.fastcs_adapter import (
    records_of,
    shape_problems,
    version_problems,
)
from fastcs_ethercat.process import ChildProcess
from tests.conftest import TEST_DATA
from tests.ioc_support import (
    START_TIMEOUT,
    IocProcess,
    caget,
    command,
    ioc_env,
    new_token,
    start_ioc,
    wait_for,
)
from tests.processes import run_python_child, wait_for_line

NAMES = ("Temperature", "Mode", "Samples", "Output", "CoeGain", "Setting", "Refusing")
CA_NAMES = (
    "Temperature", "Mode", "Samples", "Output_RBV", "Output",
    "CoeGain_RBV", "CoeGain", "Setting_RBV", "Setting", "Refusing",
)  # fmt: skip
SCALAR_PVA_NAMES = tuple(name for name in CA_NAMES if name != "Samples")


def test_installed_packages_have_the_shape_the_adapter_reads() -> None:
    assert version_problems() == []
    assert shape_problems() == []


def test_an_attribute_without_records_has_no_alarm_to_show() -> None:
    attribute = AttrR(Int())

    records = records_of(attribute)
    assert records.readback is None and records.setpoint is None
    assert publish_alarm(attribute, AlarmState(Severity.INVALID, Status.COMM)) == 0


@pytest.fixture(scope="module")
def ioc() -> Iterator[IocProcess]:
    token = new_token()
    prefix = f"ALM{token[:6].upper()}"
    process = start_commanded_ioc(prefix, token, [])
    try:
        process.wait_for_line("alarm ioc ready", START_TIMEOUT)
        first = process.pv("Temperature")
        assert wait_for(lambda: first in caget(process, first), START_TIMEOUT)
        yield process
    finally:
        process.stop()


def start_commanded_ioc(
    prefix: str, token: str, arguments: Sequence[str]
) -> IocProcess:
    """tests/data/alarm_ioc.py with a pipe to its stdin for commands."""
    env = ioc_env(token)
    command = [sys.executable, str(TEST_DATA / "alarm_ioc.py"), "--prefix", prefix]
    return start_ioc([*command, *arguments], prefix, env, token, commands=True)


def ca_alarms(ioc: IocProcess, names: Sequence[str]) -> dict[str, str]:
    """`STAT SEVR` of each record as `caget -a` prints them ("" when none)."""
    values = caget(ioc, "-a", *(ioc.pv(name) for name in names))
    result = {}
    for name in names:
        words = values.get(ioc.pv(name), "").split()
        tail = words[-2:]
        alarmed = len(tail) == 2 and tail[1] in {"MINOR", "MAJOR", "INVALID"}
        result[name] = " ".join(tail) if alarmed else ""
    return result


def aioca_alarms(ioc: IocProcess, names: Sequence[str]) -> dict[str, list[int]]:
    """[severity, status] of each PV read by aioca with FORMAT_TIME."""
    script = (
        "import asyncio, aioca, json, sys\n"
        "async def main(names):\n"
        "    values = await aioca.caget(names, format=aioca.FORMAT_TIME, timeout=10)\n"
        "    print(json.dumps({n: [v.severity, v.status]"
        " for n, v in zip(names, values)}))\n"
        "asyncio.run(main(sys.argv[1:]))\n"
    )
    pvs = [ioc.pv(name) for name in names]
    done = run_python_child(script, *pvs, env=ioc.env, timeout=60)
    by_pv = json.loads(done.stdout.strip().splitlines()[-1])
    return {name: by_pv[ioc.pv(name)] for name in names}


def p4p_alarms(ioc: IocProcess, names: Sequence[str]) -> dict[str, dict[str, Any]]:
    with ioc.p4p_context() as context:
        values: Any = context.get([ioc.pv(name) for name in names])
    return {
        name: as_dict(value)["alarm"] for name, value in zip(names, values, strict=True)
    }


def pvget_severities(ioc: IocProcess, names: Sequence[str]) -> dict[str, int]:
    """alarm.severity from `pvget -M json` (JSON5-like: keys are not quoted)."""
    output = ioc.tool("pvget", "-M", "json", *(ioc.pv(name) for name in names))
    severities = {}
    for line in output.splitlines():
        pv, _, text = line.partition(" ")
        found = re.search(r"alarm:\{severity:(\d)", text)
        if pv.startswith(ioc.prefix) and found:
            severities[pv.split(":", 1)[1]] = int(found.group(1))
    return severities


@pytest.mark.e2e
def test_target_lost_shows_invalid_comm_everywhere_then_clears(
    ioc: IocProcess,
) -> None:
    started = time.monotonic()
    reached = command(ioc, "alarm-all INVALID COMM")
    seen = wait_for(
        lambda: all(v == "COMM INVALID" for v in ca_alarms(ioc, CA_NAMES).values())
    )
    seen_after = time.monotonic() - started
    on_ca = ca_alarms(ioc, CA_NAMES)
    on_aioca = aioca_alarms(ioc, CA_NAMES)
    on_p4p = p4p_alarms(ioc, SCALAR_PVA_NAMES)
    on_pvget = pvget_severities(ioc, SCALAR_PVA_NAMES)
    waveform = p4p_alarms(ioc, ["Samples"])["Samples"]
    for name in NAMES:
        command(ioc, f"clear {name}")
    cleared = ca_alarms(ioc, CA_NAMES)
    cleared_pva = p4p_alarms(ioc, SCALAR_PVA_NAMES)

    # 3 read-only attributes x an in record, 3 read-write x (in + out),
    # 1 write-only x an out record: PVA serves the same records
    assert reached == 3 * 1 + 3 * 2 + 1 * 1
    assert seen, on_ca
    print(f"\nalarm seen by caget {seen_after:.2f} s after the command")
    assert set(on_ca.values()) == {"COMM INVALID"}
    assert all(value == [3, 9] for value in on_aioca.values()), on_aioca
    assert all(
        alarm == {"severity": 3, "status": 2, "message": "COMM"}
        for alarm in on_p4p.values()
    ), on_p4p
    assert on_pvget == dict.fromkeys(SCALAR_PVA_NAMES, 3)
    assert waveform["severity"] == 3 and waveform["message"] == "COMM"
    assert set(cleared.values()) == {""}, cleared
    assert all(alarm["severity"] == 0 for alarm in cleared_pva.values())


@pytest.mark.e2e
def test_only_the_alarmed_attribute_goes_into_alarm(ioc: IocProcess) -> None:
    command(ioc, "alarm Mode MINOR STATE terminal left OP")
    wait_for(lambda: ca_alarms(ioc, ["Mode"])["Mode"])
    on_ca = ca_alarms(ioc, ["Mode", "Temperature", "Output_RBV"])
    on_p4p = p4p_alarms(ioc, ["Mode", "Temperature"])
    command(ioc, "clear Mode")

    assert on_ca == {"Mode": "STATE MINOR", "Temperature": "", "Output_RBV": ""}
    # QSRV: status DEVICE, the record's AMSG as the message: status and text
    assert on_p4p["Mode"] == {
        "severity": 1,
        "status": 1,
        "message": "STATE: terminal left OP",
    }
    assert on_p4p["Temperature"]["severity"] == 0


@pytest.mark.e2e
def test_a_new_value_clears_the_alarm(ioc: IocProcess) -> None:
    command(ioc, "alarm Temperature INVALID READ")
    wait_for(lambda: ca_alarms(ioc, ["Temperature"])["Temperature"])
    command(ioc, "update Temperature 30.25")

    after = wait_for(
        lambda: (
            (v := caget(ioc, "-a", ioc.pv("Temperature"))[ioc.pv("Temperature")])
            and "30.25" in v
            and v
        )
    )
    on_p4p = p4p_alarms(ioc, ["Temperature"])

    assert after and not after.endswith("INVALID"), after
    assert on_p4p["Temperature"]["severity"] == 0


MONITOR_SCRIPT = """
import asyncio, aioca, json, sys
async def main(name, seconds):
    def show(value):
        print(json.dumps([value.severity, value.status, float(value)]), flush=True)
    subscription = aioca.camonitor(name, show, format=aioca.FORMAT_TIME)
    await asyncio.sleep(seconds)
    subscription.close()
asyncio.run(main(sys.argv[1], float(sys.argv[2])))
"""


@pytest.mark.e2e
def test_a_monitor_sees_an_output_record_go_into_alarm_and_out(
    ioc: IocProcess,
) -> None:
    monitor = ChildProcess(
        [sys.executable, "-c", MONITOR_SCRIPT, ioc.pv("Output"), "6"],
        "monitor",
        env=ioc.env,
    )
    with monitor:
        monitor.launch()
        wait_for_line(monitor, r"^\[", 30)  # connected: the first update
        command(ioc, "alarm Output MAJOR WRITE")
        time.sleep(0.5)
        command(ioc, "clear Output")
        monitor.wait(30)
    updates = [json.loads(line) for line in monitor.lines]

    assert updates == [[0, 0, 5.0], [2, 2, 5.0], [0, 0, 5.0]]


def as_dict(value: Any) -> dict[str, Any]:
    """A p4p Value, or a p4p-unwrapped one (ntfloat, ntenum...), as a dict."""
    return getattr(value, "raw", value).todict()


@pytest.mark.e2e
def test_a_refused_write_puts_the_output_in_alarm(ioc: IocProcess) -> None:
    """FastCS itself does this when the IO's send raises (an ADS write error);
    the put completes on either protocol, the record's alarm says it failed."""
    name = ioc.pv("Refusing")
    ioc.tool("caput", name, "3")
    on_ca = wait_for(lambda: ca_alarms(ioc, ["Refusing"])["Refusing"])
    command(ioc, "clear Refusing")
    with ioc.p4p_context() as context:
        context.put(name, 4, wait=True)  # completes once the record has processed
        on_pva = as_dict(context.get(name))["alarm"]

    assert on_ca == "WRITE MAJOR"
    assert on_pva["severity"] == Severity.MAJOR
