"""The served PVs behave as the EPICS records they are, end to end.

One simulator with the demo chain, one IOC with a site database beside its
own records; real `caput`/`caget`/`camonitor`/`pvget`. The value under test
is Term 22's (EL3104) first channel, `...:MOD22:CH1:Value` (an `ai`, volts),
driven by setting its raw count in the simulator (32767 counts = 10 V).
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    BIN,
    IOC_COMMAND,
    START_TIMEOUT,
    IocProcess,
    caget,
    ioc_env,
    new_token,
    start_ioc,
    stop_pid,
    wait_for,
    write_ioc_config,
)
from tests.processes import run_cli_child

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
RAW = "Term 22 (EL3104).AI Standard Channel 1.Value"
VALUE = "ETH1:RIO21:MOD22:CH1:Value"
SITE_DB = """\
record(calc, "$(P):SITE:$(NAME)") {
    field(INPA, "$(P):ETH1:RIO21:MOD22:CH1:Value CP")
    field(CALC, "A*2")
}
"""
COUNTS_PER_VOLT = 32767 / 10


@dataclass
class Rack:
    sim: SimProcess
    ioc: IocProcess

    @property
    def value(self) -> str:
        return self.ioc.pv(VALUE)

    def set_volts(self, volts: float) -> None:
        self.sim.set_symbol(RAW, round(volts * COUNTS_PER_VOLT))

    def put(self, field: str, value: str) -> None:
        out = self.ioc.tool("caput", f"{self.value}.{field}", value)
        assert "New" in out, out

    def reads(self, volts: float) -> bool:
        """Whether the value shows `volts` (to 1 mV) now."""
        found = caget(self.ioc, self.value).get(self.value)
        return found is not None and abs(float(found) - volts) < 1e-3

    def alarm(self) -> list[str]:
        """[value, status, severity] (just [value] without an alarm)."""
        return caget(self.ioc, "-a", self.value)[self.value].split()[2:]


@pytest.fixture(scope="module")
def rack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rack]:
    token = new_token()
    work = tmp_path_factory.mktemp("records")
    env = ioc_env(token)
    prefix = f"TST{token[:6].upper()}"
    (work / "site.db").write_text(SITE_DB)
    with SimProcess(chain=DEMO_CHAIN, terminals=TERMINALS_DIR, env=env) as sim:
        config = write_ioc_config(
            work,
            prefix,
            sim.pyads_ip,
            sim.net_id,
            poll_rate_hz=20,
            databases=[{"file": "site.db", "macros": {"NAME": "Double"}}],
        )
        ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
        try:
            ioc.wait_for_line("ioc ready", START_TIMEOUT)
            rack = Rack(sim, ioc)
            rack.set_volts(1.0)
            assert wait_for(lambda: rack.reads(1.0), 30)
            yield rack
        finally:
            ioc.stop()
            if ioc.child.returncode is None:
                stop_pid(ioc.child.pid)


def _reset(rack: Rack) -> None:
    for field, value in (
        ("HIHI", "0"),
        ("HHSV", "NO_ALARM"),
        ("HYST", "0"),
        ("ADEL", "0"),
        ("MDEL", "0"),
    ):
        rack.put(field, value)


@pytest.fixture
def fields(rack: Rack) -> Iterator[Rack]:
    """The rack, its value's fields back at their defaults afterwards."""
    try:
        yield rack
    finally:
        _reset(rack)


def _settle(rack: Rack, volts: float) -> None:
    rack.set_volts(volts)
    assert wait_for(lambda: rack.reads(volts), 10), volts
    time.sleep(0.2)  # a few poll cycles: the record has processed it


OUTPUT = "ETH1:RIO21:MOD24:CH3:AnalogOutput"  # Term 24 (EP4374-0002), volts


def test_operator_fields_and_the_display_range(rack: Rack) -> None:
    """An ordinary EPICS input record: soft device support, processed when
    its value is put, its time its processing's, open to operators."""
    names = ("DTYP", "SCAN", "DISP", "HOPR", "LOPR", "EGU", "TSE", "TSEL")
    found = caget(rack.ioc, *(f"{rack.value}.{name}" for name in names))
    shown = {name: found[f"{rack.value}.{name}"] for name in names}
    assert [shown[name] for name in ("DTYP", "SCAN", "DISP", "EGU")] == [
        "Soft Channel",
        "Passive",
        "0",
        "V",
    ]
    assert (shown["TSE"], shown["TSEL"]) == ("0", "")
    assert float(found[f"{rack.value}.HOPR"]) == pytest.approx(10.0)
    assert float(found[f"{rack.value}.LOPR"]) == pytest.approx(-10.0, abs=1e-3)


def test_an_output_has_its_range_for_display_and_drive(rack: Rack) -> None:
    output = rack.ioc.pv(OUTPUT)
    names = ("HOPR", "LOPR", "DRVH", "DRVL")
    found = caget(rack.ioc, *(f"{output}.{name}" for name in names))
    hopr, lopr, drvh, drvl = (float(found[f"{output}.{name}"]) for name in names)

    assert (hopr, lopr) == (drvh, drvl)
    assert hopr > lopr


def test_hihi_raises_major_and_hyst_holds_it(fields: Rack) -> None:
    rack = fields
    _settle(rack, 5.0)
    rack.put("HYST", "1")
    rack.put("HHSV", "MAJOR")
    rack.put("HIHI", "4")
    rack.put("PROC", "1")  # the limits apply from the next processing
    raised = wait_for(lambda: rack.alarm()[1:] == ["HIHI", "MAJOR"], 10)
    on_pva = rack.ioc.tool("pvget", "-M", "json", rack.value)
    _settle(rack, 3.5)  # below HIHI, within HYST of it: still in alarm
    held = rack.alarm()
    _settle(rack, 2.5)  # below HIHI - HYST: cleared
    cleared = rack.alarm()

    assert raised
    assert re.search(r"alarm:\{severity:2,status:\d,message:\"HIHI\"", on_pva), on_pva
    assert held[1:] == ["HIHI", "MAJOR"]
    assert len(cleared) == 1, cleared


def _events(rack: Rack, mask: str, during: Callable[[], None]) -> list[str]:
    """The value lines `camonitor -m MASK` prints while `during()` runs (the
    first is the one at connection)."""
    monitor = start_ioc(
        [str(BIN / "camonitor"), "-m", mask, rack.value],
        rack.ioc.prefix,
        rack.ioc.env,
        rack.ioc.token,
    )
    try:
        monitor.wait_for_line(re.escape(rack.value), 10)
        during()
        time.sleep(0.5)
    finally:
        stop_pid(monitor.child.pid)
        monitor.child.wait(5)
    monitor.unread()  # into its output
    return [line for line in monitor.output if rack.value in line]


def test_alarm_monitors_see_only_alarm_transitions(fields: Rack) -> None:
    rack = fields
    _settle(rack, 1.0)
    rack.put("HHSV", "MINOR")
    rack.put("HIHI", "4")

    def changes() -> None:
        for volts in (1.5, 2.0, 2.5, 5.0, 5.5, 6.0, 1.0):  # into alarm and out
            _settle(rack, volts)

    events = _events(rack, "a", changes)

    # at connection, into HIHI at 5 V, out of it at 1 V: not the other four
    assert len(events) == 3, events
    assert events[1].split()[-2:] == ["HIHI", "MINOR"]


def test_adel_governs_archive_events(fields: Rack) -> None:
    rack = fields
    _settle(rack, 1.0)
    steps = (1.2, 1.4, 1.6, 2.5, 2.7, 4.0)

    def changes() -> None:
        for volts in steps:
            _settle(rack, volts)

    rack.put("ADEL", "1")
    beyond = _events(rack, "l", changes)
    _settle(rack, 1.0)
    rack.put("ADEL", "0")
    every = _events(rack, "l", changes)

    # ADEL 1 from 1.0 V: 2.5 (1.5 away) and 4.0 (1.5 from 2.5), not the rest
    assert [line.split()[-1][:3] for line in beyond[1:]] == ["2.5", "4.0"], beyond
    assert len(every) == 1 + len(steps), every


def test_a_value_carries_its_channels_status_alarm(rack: Rack) -> None:
    """A forced Error bit turns the channel's value MAJOR (STATE) with it,
    an Overrange bit MINOR; cleared, the value is back to no alarm."""
    _settle(rack, 1.0)
    channel = "Term 22 (EL3104).AI Standard Channel 1.Status."
    rack.sim.set_symbol(channel + "Error", 1)
    raised = wait_for(lambda: rack.alarm()[1:] == ["STATE", "MAJOR"], 10)
    pva = rack.ioc.tool("pvget", "-M", "json", rack.value)
    rack.sim.set_symbol(channel + "Error", 0)
    rack.sim.set_symbol(channel + "Overrange", 1)
    minor = wait_for(lambda: rack.alarm()[1:] == ["STATE", "MINOR"], 10)
    rack.sim.set_symbol(channel + "Overrange", 0)
    cleared = wait_for(lambda: len(rack.alarm()) == 1, 10)

    assert raised, rack.alarm()
    assert re.search(r"alarm:\{severity:2", pva), pva
    assert minor, rack.alarm()
    assert cleared, rack.alarm()


def test_a_site_calc_record_follows_the_value_by_its_cp_link(rack: Rack) -> None:
    double = rack.ioc.pv("SITE:Double")

    def shows(volts: float) -> bool:
        found = caget(rack.ioc, double).get(double)
        return found is not None and abs(float(found) - volts) < 2e-3

    _settle(rack, 1.5)
    first = wait_for(lambda: shows(3.0), 10)
    _settle(rack, 2.0)
    then = wait_for(lambda: shows(4.0), 10)

    assert first and then, caget(rack.ioc, double)


def test_pva_shows_the_display_range(rack: Rack) -> None:
    out = rack.ioc.tool("pvget", "-v", rack.value)

    assert re.search(r"limitHigh\s+10", out), out
    assert re.search(r"limitLow\s+-10", out), out


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ('record(calc, "$(P):X") {\n  field(NOPE, 1)\n}\n', "could not load"),
        ('record(calc, "$(P):X") {\n  field(CALC, "A")\n', "never closed"),
    ],
    ids=["unknown-field", "unclosed"],
)
def test_a_site_database_that_does_not_load_stops_the_ioc(
    rack: Rack, tmp_path: Path, text: str, said: str
) -> None:
    (tmp_path / "broken.db").write_text(text)
    config = write_ioc_config(
        tmp_path,
        "TSTBROKEN",
        rack.sim.pyads_ip,
        rack.sim.net_id,
        databases=[{"file": "broken.db"}],
    )
    done = run_cli_child("ioc", "--config", config, env=rack.ioc.env, timeout=60)

    assert done.returncode == 2, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert "broken.db" in last and said in last, done.stderr[-2000:]


def test_operator_settings_survive_a_restart_and_no_output_is_written(
    rack: Rack, tmp_path: Path
) -> None:
    """softioc's autosave keeps what was set; the next start has it before
    it serves, and writes nothing to the PLC (outputs are never restored)."""
    token = new_token()
    env = ioc_env(token)
    prefix = f"TST{token[:6].upper()}"
    config = write_ioc_config(
        tmp_path,
        prefix,
        rack.sim.pyads_ip,
        rack.sim.net_id,
        autosave_dir="autosave",
    )
    value = f"{prefix}:{VALUE}"
    output = f"{prefix}:ETH1:RIO18:MOD20:CH1:Output"

    def served() -> IocProcess:
        ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
        ioc.wait_for_line("ioc ready", START_TIMEOUT)
        return ioc

    first = served()
    try:
        for pv, setting in ((f"{value}.HIHI", "7.5"), (f"{value}.DESC", "beam")):
            assert "New" in first.tool("caput", pv, setting)
        assert "New" in first.tool("caput", f"{output}.OSV", "MINOR")
        first.tool("caput", "-c", output, "1")  # an output set: not kept
    finally:
        stopped = first.stop()  # before the first periodic save: saved at exit
    rack.sim.reset_counters()
    second = served()
    try:
        kept = caget(second, f"{value}.HIHI", f"{value}.DESC", f"{output}.OSV")
        written = rack.sim.counters()
    finally:
        second.stop()

    assert stopped == 0  # SIGTERM ends the IOC, autosave's thread included
    assert float(kept[f"{value}.HIHI"]) == 7.5
    assert kept[f"{value}.DESC"] == "beam"
    assert kept[f"{output}.OSV"] == "MINOR"
    assert written["commands"].get("Write", 0) == 0, written
    assert "0xF081" not in written["index_groups"], written  # no sum write either
    saved = (tmp_path / "autosave" / f"{prefix}.softsav").read_text()
    assert f"{value}.HIHI" in saved and f"{output}:" not in saved
