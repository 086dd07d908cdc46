"""The FastCS plumbing end to end, without ADS: our launcher in a subprocess.

The spike IOC (`fastcs_ethercat.ioc.spike`) serves CA and PVA on ports of its
own, so it cannot meet another test's IOC. Real clients talk to it: the
`caget`/`caput`/`pvget` binaries of .venv/bin (their wrappers always exit 0,
so their output is what counts), aioca (in a subprocess, as its CA context is
one per process) and p4p. The IOC and any caRepeater it or the clients
spawned are killed by PID at the end.
"""

from __future__ import annotations

import contextlib
import os
import queue
import re
import secrets
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from p4p.client.thread import Context

from fastcs_ethercat.ioc.launch import parse_ready_line
from tests.conftest import loopback_env

BIN = Path(sys.executable).parent
START_TIMEOUT = 90.0
TERMINAL = "ETH1:RIO1:MOD5"


def _free_port(tcp: bool, udp: bool) -> int:
    """A loopback port free for TCP and/or UDP right now."""
    for _ in range(200):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        sockets = []
        try:
            if tcp:
                sockets.append(socket.socket(socket.AF_INET, socket.SOCK_STREAM))
                sockets[-1].bind(("127.0.0.1", port))
            if udp:
                sockets.append(socket.socket(socket.AF_INET, socket.SOCK_DGRAM))
                sockets[-1].bind(("127.0.0.1", port))
            return port
        except OSError:
            continue
        finally:
            for sock in sockets:
                sock.close()
    raise RuntimeError("no free port")


@dataclass
class SpikeIoc:
    process: subprocess.Popen[str]
    prefix: str
    env: dict[str, str]
    token: str
    screens: Path
    lines: queue.Queue[str]
    output: list[str] = field(default_factory=list)
    figures: dict[str, float] = field(default_factory=dict)

    def pv(self, name: str) -> str:
        return f"{self.prefix}:{name}"

    def wait_for_line(self, pattern: str, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                if self.process.poll() is not None:
                    break
                continue
            self.output.append(line)
            if re.search(pattern, line):
                return line
        tail = "".join(self.output[-30:])
        raise AssertionError(f"no line matching {pattern!r}; output:\n{tail}")

    def tool(self, *args: str, timeout: float = 30) -> str:
        """Run a CA/PVA command-line tool against this IOC; return its output."""
        done = subprocess.run(
            [str(BIN / args[0]), *args[1:]],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        return done.stdout + done.stderr

    def p4p_context(self) -> Context:
        return Context(
            "pva",
            conf={
                "EPICS_PVA_ADDR_LIST": "127.0.0.1",
                "EPICS_PVA_AUTO_ADDR_LIST": "NO",
                "EPICS_PVA_BROADCAST_PORT": self.env["EPICS_PVA_BROADCAST_PORT"],
                "EPICS_PVA_SERVER_PORT": self.env["EPICS_PVA_SERVER_PORT"],
            },
            useenv=False,
        )


def _processes_with_token(token: str) -> list[int]:
    """PIDs whose environment carries our token (the IOC's caRepeater too)."""
    found = []
    marker = f"FASTCS_ETHERCAT_TEST_TOKEN={token}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker in (entry / "environ").read_bytes().split(b"\0"):
                found.append(int(entry.name))
        except OSError:
            continue
    return found


def _stop(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    for _ in range(50):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)


@pytest.fixture(scope="module")
def ioc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SpikeIoc]:
    token = secrets.token_hex(8)
    prefix = f"TST{token[:6].upper()}"
    screens = tmp_path_factory.mktemp("screens")
    env = loopback_env(
        EPICS_CA_SERVER_PORT=str(_free_port(tcp=True, udp=True)),
        EPICS_CA_REPEATER_PORT=str(_free_port(tcp=False, udp=True)),
        EPICS_PVA_SERVER_PORT=str(_free_port(tcp=True, udp=False)),
        EPICS_PVA_BROADCAST_PORT=str(_free_port(tcp=False, udp=True)),
        FASTCS_ETHERCAT_TEST_TOKEN=token,
        PYTHONUNBUFFERED="1",
    )
    command = [sys.executable, "-m", "fastcs_ethercat.ioc.spike"]
    arguments = ["--prefix", prefix, "--screens", str(screens), "--measure", "100"]
    started = time.monotonic()
    process = subprocess.Popen(
        command + arguments,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: queue.Queue[str] = queue.Queue()
    assert process.stdout is not None
    stdout = process.stdout
    reader = threading.Thread(
        target=lambda: [lines.put(x) for x in stdout], daemon=True
    )
    reader.start()
    spike = SpikeIoc(process, prefix, env, token, screens, lines)
    try:
        ready = spike.wait_for_line("ioc ready", START_TIMEOUT)
        spike.figures["ready_s"] = time.monotonic() - started
        assert parse_ready_line(ready.strip()) == {"prefix": prefix}
        counter = spike.pv("Counter")
        assert _wait_for(lambda: counter in _caget(spike, counter), START_TIMEOUT)
        spike.figures["first_caget_s"] = time.monotonic() - started
        yield spike
    finally:
        _stop(process.pid)
        process.wait(10)
        for pid in _processes_with_token(token):
            _stop(pid)
        reader.join(5)


def _caget(ioc: SpikeIoc, *flags_and_names: str) -> dict[str, str]:
    """caget's `NAME VALUE...` lines as a dict (value: the rest of the line)."""
    output = ioc.tool("caget", *flags_and_names)
    values = {}
    for line in output.splitlines():
        name, _, value = line.partition(" ")
        if name.startswith(ioc.prefix):
            values[name] = value.strip()
    return values


def _wait_for(check: Any, timeout: float = 10.0) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        result = check()
        if result or time.monotonic() > deadline:
            return result
        time.sleep(0.1)


def test_ioc_starts_and_reports_how_long_it_took(ioc: SpikeIoc) -> None:
    print(
        f"\nspike IOC: ready line after {ioc.figures['ready_s']:.2f} s, "
        f"first caget answer after {ioc.figures['first_caget_s']:.2f} s"
    )
    assert 0 < ioc.figures["ready_s"] <= ioc.figures["first_caget_s"]


def test_caget_reads_every_datatype(ioc: SpikeIoc) -> None:
    t = f"{TERMINAL}:"
    plain = _caget(
        ioc,
        ioc.pv("Counter"),
        ioc.pv("ETH1:SlaveCount"),
        ioc.pv(t + "AIStdCh1Value"),
        ioc.pv(t + "AIStdCh1StatusOverrange"),
        ioc.pv(t + "SettingsMode_RBV"),
        ioc.pv(t + "OversamplingSamples"),
    )
    exact = _caget(ioc, "-g17", ioc.pv(t + "ScaledValue"))
    whole = _caget(ioc, "-f0", ioc.pv(t + "CNTInputsCounterValue"))
    text = _caget(ioc, "-S", ioc.pv(t + "InfoName"))

    assert int(plain[ioc.pv("Counter")]) >= 0
    assert plain[ioc.pv("ETH1:SlaveCount")] == "3"
    assert plain[ioc.pv(t + "AIStdCh1Value")] == "-1234"
    assert plain[ioc.pv(t + "AIStdCh1StatusOverrange")] == "True"
    assert plain[ioc.pv(t + "SettingsMode_RBV")] == "Unsigned"
    assert plain[ioc.pv(t + "OversamplingSamples")].split() == [
        "8", "-4", "-3", "-2", "-1", "0", "1", "2", "3"
    ]  # fmt: skip
    assert float(exact[ioc.pv(t + "ScaledValue")]) == 1.2345678901234567
    assert whole[ioc.pv(t + "CNTInputsCounterValue")] == "4000000001"
    assert text[ioc.pv(t + "InfoName")] == "EL3104 spike"


def test_pvget_reads_values_and_the_pvi_tree(ioc: SpikeIoc) -> None:
    t = f"{TERMINAL}:"
    values = ioc.tool(
        "pvget",
        "-M",
        "json",
        ioc.pv(t + "ScaledValue"),
        ioc.pv(t + "CNTInputsCounterValue"),
        ioc.pv(t + "SettingsMode_RBV"),
    )
    root_pvi = ioc.tool("pvget", ioc.pv("PVI"))
    terminal_pvi = ioc.tool("pvget", ioc.pv(t + "PVI"))

    assert "value:1.2345678901234567," in values
    assert "value:4000000001.0," in values
    assert 'choices:["Signed","Unsigned","Absolute MSB sign"]' in values
    assert f"string d {ioc.pv('ETH1:PVI')}" in root_pvi
    assert f"string r {ioc.pv('Counter')}" in root_pvi
    assert f"string r {ioc.pv(t + 'AIStdCh1Value')}" in terminal_pvi
    assert f"string w {ioc.pv(t + 'AOOutputCh1AnalogOutput')}" in terminal_pvi
    assert f"string r {ioc.pv(t + 'AOOutputCh1AnalogOutput_RBV')}" in terminal_pvi


def test_p4p_reads_exact_values_and_puts_within_range(ioc: SpikeIoc) -> None:
    t = f"{TERMINAL}:"
    output = ioc.pv(t + "AOOutputCh1AnalogOutput")
    with ioc.p4p_context() as context:
        scaled: Any = context.get(ioc.pv(t + "ScaledValue"))
        counter: Any = context.get(ioc.pv(t + "CNTInputsCounterValue"))
        context.put(output, -7)
        readback = _wait_for(lambda: context.get(output + "_RBV") == -7)
        with pytest.raises(TimeoutError):
            # FastCS 0.14.4 validates a PVA put before its try block, so an
            # out-of-range put is never completed: the client times out.
            context.put(output, 1000, timeout=2.0)
        after: Any = context.get(output + "_RBV")

    assert float(scaled) == 1.2345678901234567
    assert float(counter) == 4_000_000_001
    assert readback
    assert int(after) == -7


def test_caput_writes_and_aioca_reads_back(ioc: SpikeIoc) -> None:
    t = f"{TERMINAL}:"
    enable = ioc.pv(t + "OutputsEnable")
    output = ioc.pv(t + "AOOutputCh1AnalogOutput")
    ioc.tool("caput", enable, "1")
    ioc.tool("caput", "-S", ioc.pv(t + "SettingsMode"), "Absolute MSB sign")
    ioc.tool("caput", output, "1000")  # CA clamps to DRVH = 127 (SINT max)

    def read_with_aioca() -> dict[str, str]:
        script = (
            "import asyncio, aioca\n"
            "async def main(names):\n"
            "    values = await aioca.caget(names, format=aioca.FORMAT_CTRL)\n"
            "    for name, value in zip(names, values):\n"
            "        print(name, repr(value.real if hasattr(value, 'real')"
            " else value))\n"
            "import sys\n"
            "asyncio.run(main(sys.argv[1:]))\n"
        )
        names = [enable + "_RBV", ioc.pv(t + "SettingsMode_RBV"), output + "_RBV"]
        done = subprocess.run(
            [sys.executable, "-c", script, *names],
            env=ioc.env,
            capture_output=True,
            text=True,
            timeout=60,
        )
        return dict(
            line.split(" ", 1)
            for line in done.stdout.splitlines()
            if line.startswith(ioc.prefix)
        )

    values = _wait_for(
        lambda: (v := read_with_aioca()) and v.get(output + "_RBV") == "127" and v
    )

    assert values[enable + "_RBV"] == "1"
    assert values[ioc.pv(t + "SettingsMode_RBV")] == "2"  # mbbi index of value 5
    assert values[output + "_RBV"] == "127"


def test_screens_hold_every_attribute(ioc: SpikeIoc) -> None:
    files = sorted(path.name for path in ioc.screens.glob("*.bob"))
    terminal_screen = (ioc.screens / f"{ioc.prefix}_ETH1_RIO1_MOD5.bob").read_text()

    assert {"index.bob", f"{ioc.prefix}.bob", f"{ioc.prefix}_ETH1.bob"} <= set(files)
    for name in (
        "AIStdCh1Value",
        "AIStdCh1StatusOverrange",
        "CNTInputsCounterValue",
        "ScaledValue",
        "InfoName",
        "SettingsMode_RBV",
        "AOOutputCh1AnalogOutput_RBV",
        "OutputsEnable",
    ):
        assert ioc.pv(f"{TERMINAL}:{name}") in terminal_screen


def test_update_cost_is_measured(ioc: SpikeIoc) -> None:
    line = ioc.wait_for_line("^measure:", 60)
    figures = dict(item.split("=") for item in line.split(":", 1)[1].split())
    print(f"\nattribute.update() with CA + PVA attached, in microseconds: {figures}")

    assert set(figures) == {"changed_us", "unchanged_us", "gather_us"}
    assert all(float(value) > 0 for value in figures.values())
