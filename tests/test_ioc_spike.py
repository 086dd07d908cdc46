"""The FastCS plumbing end to end, without ADS: our launcher in a subprocess.

The spike IOC (`fastcs_ethercat.ioc.spike`) serves CA and PVA on ports of its
own, so it cannot meet another test's IOC. Real clients talk to it: the
`caget`/`caput`/`pvget` binaries of .venv/bin (their wrappers always exit 0,
so their output is what counts), aioca (in a subprocess, as its CA context is
one per process) and p4p. The IOC and any caRepeater it or the clients
spawned are killed by PID at the end.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest

from fastcs_ethercat.ioc.launch import parse_ready_line
from tests.ioc_support import (
    START_TIMEOUT,
    IocProcess,
    aioca_get,
    caget,
    ioc_env,
    new_token,
    start_ioc,
    wait_for,
)

pytestmark = pytest.mark.e2e

TERMINAL = "ETH1:RIO1:MOD5"


@pytest.fixture(scope="module")
def ioc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IocProcess]:
    token = new_token()
    prefix = f"TST{token[:6].upper()}"
    screens = tmp_path_factory.mktemp("screens")
    command = [sys.executable, "-m", "fastcs_ethercat.ioc.spike"]
    arguments = ["--prefix", prefix, "--screens", str(screens), "--measure", "100"]
    started = time.monotonic()
    spike = start_ioc(command + arguments, prefix, ioc_env(token), token)
    spike.screens = screens  # type: ignore[attr-defined]
    try:
        ready = spike.wait_for_line("ioc ready", START_TIMEOUT)
        spike.figures["ready_s"] = time.monotonic() - started
        assert parse_ready_line(ready.strip()) == {"prefix": prefix}
        counter = spike.pv("Counter")
        assert wait_for(lambda: counter in _caget(spike, counter), START_TIMEOUT)
        spike.figures["first_caget_s"] = time.monotonic() - started
        yield spike
    finally:
        spike.stop()


_caget = caget
_wait_for = wait_for


def test_ioc_starts_and_reports_how_long_it_took(ioc: Any) -> None:
    print(
        f"\nspike IOC: ready line after {ioc.figures['ready_s']:.2f} s, "
        f"first caget answer after {ioc.figures['first_caget_s']:.2f} s"
    )
    assert 0 < ioc.figures["ready_s"] <= ioc.figures["first_caget_s"]


def test_caget_reads_every_datatype(ioc: Any) -> None:
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


def test_pvget_reads_values_and_the_pvi_tree(ioc: Any) -> None:
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


def test_p4p_reads_exact_values_and_puts_within_range(ioc: Any) -> None:
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


def test_caput_writes_and_aioca_reads_back(ioc: Any) -> None:
    t = f"{TERMINAL}:"
    enable = ioc.pv(t + "OutputsEnable")
    output = ioc.pv(t + "AOOutputCh1AnalogOutput")
    ioc.tool("caput", enable, "1")
    ioc.tool("caput", "-S", ioc.pv(t + "SettingsMode"), "Absolute MSB sign")
    ioc.tool("caput", output, "1000")  # CA clamps to DRVH = 127 (SINT max)

    def read_with_aioca() -> dict[str, str]:
        names = [enable + "_RBV", ioc.pv(t + "SettingsMode_RBV"), output + "_RBV"]
        return aioca_get(ioc, names)

    values = _wait_for(
        lambda: (v := read_with_aioca()) and v.get(output + "_RBV") == "127" and v
    )

    assert values[enable + "_RBV"] == "1"
    assert values[ioc.pv(t + "SettingsMode_RBV")] == "2"  # mbbi index of value 5
    assert values[output + "_RBV"] == "127"


def test_screens_hold_every_attribute(ioc: Any) -> None:
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


def test_update_cost_is_measured(ioc: Any) -> None:
    line = ioc.wait_for_line("^measure:", 60)
    figures = dict(item.split("=") for item in line.split(":", 1)[1].split())
    print(f"\nupdate() and Publisher with CA + PVA attached, in µs: {figures}")

    assert set(figures) == {"changed_us", "unchanged_us", "gather_us", "published_us"}
    assert all(float(value) > 0 for value in figures.values())
