"""Writes that tell the truth, against the simulator (one IOC for the module).

The PLC's side is read with the simulator's control API (`GET /symbols`),
the IOC's with real clients: `caput -c -l` (the put with callback, then the
record as the client sees it), `caget -a`, `pvget` and p4p.

- a write the IOC could not deliver (target refused, stalled) fails for the
  client, and the setpoint never shows NO_ALARM with a value the PLC lacks;
- CA and PVA setpoints agree after puts on either;
- 60 online changes with writes and reads at random moments, within the
  first poll cycle after a change included: every write lands on its own
  symbol (held through the change), none on another, none is reported done
  that the PLC lacks, no value of another symbol is published without an
  alarm;
- a device port that does not answer the symbol version: the invalid
  handles alone make the IOC resolve again.
"""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml
from p4p.client.thread import Context

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT
from tests.ioc_support import IocProcess, caget, served_ioc, wait_for, write_ioc_config

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
INVALID = 3
ANALOG = "ETH1:RIO21:MOD24:CH3:AnalogOutput"
ANALOG_SYMBOL = "Term 24 (EP4374-0002).AO Outputs Channel 3"
OUTPUTS = {
    # PV -> symbol: analog words served in counts (an EL4134's are volts),
    # digital bits, bits of one control word
    ANALOG: ANALOG_SYMBOL,
    "ETH1:RIO21:MOD24:CH4:AnalogOutput": "Term 24 (EP4374-0002).AO Outputs Channel 4",
    "ETH1:RIO1:MOD6:CH2:Output": "Term 6 (EL2024).Channel 2",
    "ETH1:RIO1:MOD7:CH3:Output": "Term 7 (EL2124).Channel 3",
    "ETH1:RIO1:MOD8:CH1:SetOutput": (
        "Term 8 (EL1502).CNT Outputs Channel 1.Control.Set output"
    ),
    "ETH1:RIO1:MOD8:CH1:SetCounter": (
        "Term 8 (EL1502).CNT Outputs Channel 1.Control.Set counter"
    ),
    "ETH1:RIO1:MOD8:CH1:SetCounterValue": (
        "Term 8 (EL1502).CNT Outputs Channel 1.Set counter value"
    ),
}
WATCHED_OUTPUTS = (
    # written by nobody: any change is a write that went astray
    "Term 15 (EL4134).AO Output Channel 1",
    "Term 15 (EL4134).AO Output Channel 2",
    "Term 15 (EL4134).AO Output Channel 4",
    "Term 6 (EL2024).Channel 1",
    "Term 8 (EL1502).CNT Outputs Channel 1.Control.Inhibit counter",
    "Term 8 (EL1502).CNT Outputs Channel 1.Control.Enable output functions",
    "Term 8 (EL1502).CNT Outputs Channel 2.Set counter value",
)
STANDARD = "Term 22 (EL3104).AI Standard Channel"
COMPACT = "Term 5 (EL3104).AI Compact Channel"
PINNED = {
    # PV -> (symbol, the value the simulator is made to hold): raw counts
    "ETH1:RIO21:MOD22:CH1:ValueRaw": (f"{STANDARD} 1.Value", 1111),
    "ETH1:RIO21:MOD22:CH2:ValueRaw": (f"{STANDARD} 2.Value", -2222),
    "ETH1:RIO1:MOD5:CH1:ValueRaw": (f"{COMPACT} 1", 3333),
    "ETH1:RIO1:MOD5:CH4:ValueRaw": (f"{COMPACT} 4", -4444),
}
SLAVE_COUNT = "ETH1:InputsSlaveCount"  # a runtime input: always 24 here


@dataclass
class Monitors:
    """Every PVA update of some PVs: (severity, value, alarm message)."""

    updates: dict[str, list[tuple[int, Any, str]]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def callback(self, name: str) -> Any:
        def on_update(value: Any) -> None:
            if isinstance(value, Exception):
                return
            with self.lock:
                self.updates.setdefault(name, []).append(
                    (int(value.severity), value.raw.value, str(value.raw.alarm.message))
                )

        return on_update

    def valid_values(self, name: str) -> list[Any]:
        with self.lock:
            return [
                value
                for severity, value, _ in self.updates.get(name, [])
                if not severity
            ]

    def forget(self) -> None:
        with self.lock:
            self.updates.clear()

    def count(self, name: str) -> int:
        with self.lock:
            return len(self.updates.get(name, []))


@dataclass
class Rig:
    sim: SimProcess
    ioc: IocProcess
    context: Context

    def pv(self, name: str) -> str:
        return self.ioc.pv(name)

    def root(self, name: str) -> str:
        pv = self.pv(name)
        return caget(self.ioc, "-S", pv).get(pv, "")

    def all_back(self, timeout: float = 30) -> bool:
        return bool(
            wait_for(
                lambda: (
                    self.root("ConnectionState") == "CONNECTED"
                    and self.root("InvalidPvs") == "0"
                ),
                timeout,
            )
        )

    def setpoint(self, name: str) -> tuple[str, str, str]:
        """(value, status, severity) of the CA setpoint: `caget -a` prints
        name, date, time, value, then status and severity when in alarm."""
        words = self.ioc.tool("caget", "-a", self.pv(name)).split()
        if len(words) >= 6:
            return words[3], words[4], words[5]
        return words[3], "", "NO_ALARM"


def _config(work: Path, sim: SimProcess, prefix: str) -> Path:
    return write_ioc_config(
        work, prefix, sim.pyads_ip, sim.net_id, poll_rate_hz=20, ads_timeout_ms=300
    )


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    work = tmp_path_factory.mktemp("writes")
    served = served_ioc("WRT", DEMO_CHAIN, lambda s, p: _config(work, s, p))
    with served as (sim, ioc), ioc.p4p_context() as context:
        rig = Rig(sim, ioc, context)
        assert rig.all_back(60)
        yield rig


@pytest.fixture(autouse=True)
def clean(request: pytest.FixtureRequest) -> Iterator[None]:
    """After a test with the module's rig: no fault left, every PV served."""
    yield
    if "rig" not in request.fixturenames:
        return
    rig: Rig = request.getfixturevalue("rig")
    rig.sim.clear_faults()
    assert rig.all_back(), (rig.root("ConnectionState"), rig.root("InvalidPvs"))


def _put_with_callback(rig: Rig, name: str, value: str) -> str:
    """`caput -c -l`: its last line is the record after the put completed."""
    answer = rig.ioc.tool("caput", "-c", "-l", "-w", "10", rig.pv(name), value)
    assert answer.splitlines()[-1].startswith("New : "), answer
    return answer


def _put_status(answer: str) -> str:
    """What `caput -c -l` says of the write: "WRITE" (not delivered),
    "TIMEOUT" (outcome unknown) or "" (done; another alarm status is the
    readback's, e.g. READ while the first read after a change fails)."""
    words = answer.splitlines()[-1].split()
    if words[-1] == "INVALID" and words[-2] in ("WRITE", "TIMEOUT"):
        return words[-2]
    return ""


def _put_failed(answer: str) -> bool:
    """`caput -c -l` says the IOC did not deliver the write (or cannot say
    it did)."""
    return _put_status(answer) != ""


def _truthful(rig: Rig, name: str, symbol: str) -> tuple[bool, str]:
    """The CA setpoint holds what the PLC holds, or is in alarm."""
    value, status, severity = rig.setpoint(name)
    plc = rig.sim.get_symbol(symbol)
    return (
        severity != "NO_ALARM" or value == str(plc)
    ), f"{value} {status} {severity} plc={plc}"


@pytest.mark.parametrize("kind", ["refuse", "stall"])
def test_a_put_with_callback_that_was_not_delivered_reports_a_failure(
    rig: Rig, kind: str
) -> None:
    """`caput -c` while the target refuses connections or stalls: the
    answer shows the setpoint in alarm (the IOC's INVALID, not FastCS's
    MAJOR), and from then on the setpoint never shows, without an alarm, a
    value the PLC lacks: during the fault, after it, after the reconnect."""
    rig.ioc.tool("caput", "-c", rig.pv(ANALOG), "100")
    assert wait_for(lambda: rig.sim.get_symbol(ANALOG_SYMBOL) == 100, 10)
    rig.sim.add_fault(kind, seconds=3)
    if kind == "refuse":
        assert wait_for(lambda: rig.root("ConnectionState") != "CONNECTED", 5)
    answer = _put_with_callback(rig, ANALOG, "4321")
    during = _truthful(rig, ANALOG, ANALOG_SYMBOL)
    assert rig.all_back()
    after = wait_for(
        lambda: _truthful(rig, ANALOG, ANALOG_SYMBOL)[0] and rig.setpoint(ANALOG), 10
    )
    final = _truthful(rig, ANALOG, ANALOG_SYMBOL)

    assert _put_failed(answer), answer
    assert during[0], during
    assert after and final[0], final
    if kind == "refuse":  # never delivered: the PLC kept its value
        assert rig.sim.get_symbol(ANALOG_SYMBOL) == 100


def test_a_refused_put_of_the_plcs_own_value_does_not_stay_in_alarm(rig: Rig) -> None:
    """Issue 25: a put of the value the PLC already holds, refused (the
    target away; then the target answering an error): the client sees the
    put fail, and once a readback shows the PLC's value (after the
    reconnect; a fresh one asked for after the error) the setpoint shows it
    with no alarm, as it equals what the PLC holds."""
    rig.ioc.tool("caput", "-c", rig.pv(ANALOG), "100")
    assert wait_for(lambda: rig.sim.get_symbol(ANALOG_SYMBOL) == 100, 10)
    fine = ("100", "", "NO_ALARM")
    rig.sim.add_fault("refuse", seconds=3)
    assert wait_for(lambda: rig.root("ConnectionState") != "CONNECTED", 5)
    while_away = _put_with_callback(rig, ANALOG, "100")
    assert rig.all_back()
    after_reconnect = wait_for(lambda: rig.setpoint(ANALOG) == fine, 10)
    rig.sim.add_fault("error", code=1793, group=0xF005)  # writes by handle only
    refused = _put_with_callback(rig, ANALOG, "100")
    after_refusal = wait_for(lambda: rig.setpoint(ANALOG) == fine, 10)
    final = rig.setpoint(ANALOG)

    assert _put_status(while_away) == "WRITE", while_away
    assert after_reconnect
    assert _put_status(refused) == "WRITE", refused
    assert after_refusal, final


@pytest.mark.parametrize("landed", [True, False])
def test_a_put_into_a_stall_is_decided_by_its_read_back(rig: Rig, landed: bool) -> None:
    """`caput -c` ~0.3 s into a stall of 2 s (issue 25 asked for 50 ms;
    where in the stall does not matter, only that the put is in flight
    when the IOC gives the target up): the write reaches the simulator
    (it serves requests during a stall, only the answers wait), the IOC
    loses the target and closes its port (the write in flight fails: its
    outcome is unknown, TIMEOUT). Once the target answers again the
    symbol is read back and that decides: the setpoint shows the PLC's
    value without an alarm where the write landed, INVALID/WRITE where the
    PLC does not hold it (set back during the stall).

    caput takes a while to start: the stall begins ~0.3 s before the put
    reaches the PLC as the put before it took; an attempt whose put came
    too early (answered) or too late (refused: the target already lost) is
    tried again."""
    answers: list[str] = []
    in_flight = False
    before = 100
    for attempt in range(5):
        before = 100 + attempt
        took = _put_reaching_plc(rig, before)
        fine = (str(before), "", "NO_ALARM")
        shown_fine = wait_for(lambda f=fine: rig.setpoint(ANALOG) == f, 10)
        assert shown_fine, rig.setpoint(ANALOG)
        answers.clear()
        put = threading.Thread(
            target=lambda: answers.append(_put_with_callback(rig, ANALOG, "201"))
        )
        put.start()
        time.sleep(max(0.0, took - 0.3))  # the put ~0.3 s into the stall
        rig.sim.add_fault("stall", seconds=2)
        arrived = wait_for(lambda: rig.sim.get_symbol(ANALOG_SYMBOL) == 201, 2)
        if arrived and not landed:
            rig.sim.set_symbol(ANALOG_SYMBOL, before)
        put.join(20)
        assert rig.all_back()
        in_flight = arrived and bool(answers) and _put_status(answers[0]) == "TIMEOUT"
        if in_flight:
            break
    wanted = ("201", "", "NO_ALARM") if landed else ("201", "WRITE", "INVALID")
    shown = wait_for(lambda: rig.setpoint(ANALOG) == wanted, 10)
    final = rig.setpoint(ANALOG)

    assert in_flight, answers
    assert shown, final
    assert rig.sim.get_symbol(ANALOG_SYMBOL) == (201 if landed else before)


def _put_reaching_plc(rig: Rig, value: int) -> float:
    """`caput -c` of the analog output; seconds until the PLC held it."""
    started = time.monotonic()
    put = threading.Thread(target=_put_with_callback, args=(rig, ANALOG, str(value)))
    put.start()
    assert wait_for(lambda: rig.sim.get_symbol(ANALOG_SYMBOL) == value, 10)
    took = time.monotonic() - started
    put.join(20)
    return took


def _pva_setpoint(rig: Rig, name: str) -> tuple[Any, int]:
    value: Any = rig.context.get(rig.pv(name), timeout=5)
    shown = value.raw.value
    if "index" in getattr(shown, "keys", list)():  # a bo: NTEnum on QSRV
        shown = bool(shown.index)
    return shown, int(value.severity)


def _both(rig: Rig, name: str, wanted: tuple[Any, ...]) -> tuple[Any, ...]:
    """(PVA value, PVA severity, CA value, CA status, CA severity) of a
    setpoint, once it is `wanted` (or after 5 s): an alarm lands just after
    the put's answer (PVA answers a put first, then posts its alarms)."""
    seen: list[tuple[Any, ...]] = []

    def shown() -> bool:
        seen.append((*_pva_setpoint(rig, name), *rig.setpoint(name)))
        return seen[-1] == wanted

    wait_for(shown, 5)
    return seen[-1]


def test_ca_and_pva_setpoints_agree_after_puts_on_either(rig: Rig) -> None:
    """A put on CA shows on the PVA setpoint and the other way round, for a
    write that reached the PLC and for one that did not (refused by the
    target): both show the value asked for, and both the same alarm."""
    name, bit = ANALOG, "ETH1:RIO1:MOD6:CH2:Output"
    fine, refused = ("", "NO_ALARM"), ("WRITE", "INVALID")
    rig.ioc.tool("caput", "-c", rig.pv(name), "1234")
    on_pva = _both(rig, name, (1234, 0, "1234", *fine))
    rig.context.put(rig.pv(name), 2345, timeout=5)
    on_ca = _both(rig, name, (2345, 0, "2345", *fine))
    rig.context.put(rig.pv(bit), True, timeout=5)
    bit_on_ca = _both(rig, bit, (True, 0, "True", *fine))
    rig.ioc.tool("caput", "-c", rig.pv(bit), "0")
    bit_on_pva = _both(rig, bit, (False, 0, "False", *fine))

    rig.sim.add_fault("error", code=1793, group=0xF005)  # writes by handle refused
    rig.ioc.tool("caput", "-c", rig.pv(name), "3456")
    refused_ca_put = _both(rig, name, (3456, INVALID, "3456", *refused))
    rig.context.put(rig.pv(name), 4567, timeout=5, wait=True)  # the alarm says
    refused_pva_put = _both(rig, name, (4567, INVALID, "4567", *refused))
    rig.sim.clear_faults()
    rig.context.put(rig.pv(name), 5678, timeout=5)
    healed = _both(rig, name, (5678, 0, "5678", *fine))

    assert on_pva == (1234, 0, "1234", *fine)
    assert on_ca == (2345, 0, "2345", *fine)
    assert bit_on_ca == (True, 0, "True", *fine)
    assert bit_on_pva == (False, 0, "False", *fine)
    assert refused_ca_put == (3456, INVALID, "3456", *refused)
    assert refused_pva_put == (4567, INVALID, "4567", *refused)
    assert healed == (5678, 0, "5678", *fine)
    assert rig.sim.get_symbol(ANALOG_SYMBOL) == 5678


def _log(rig: Rig) -> list[str]:
    """The IOC's lines printed since the last call."""
    return rig.ioc.unread()


def _plc(rig: Rig) -> dict[str, Any]:
    return {s: rig.sim.get_symbol(s) for s in [*OUTPUTS.values(), *WATCHED_OUTPUTS]}


def _another(value: Any, draw: random.Random) -> Any:
    if isinstance(value, bool):
        return not value
    while (chosen := draw.randint(-30000, 30000)) == value:
        pass
    return abs(chosen) if isinstance(value, int) and value >= 0 else chosen


@dataclass
class Tally:
    done: int = 0
    failed: int = 0
    unknown: int = 0
    history: list[str] = field(default_factory=list)
    astray: list[str] = field(default_factory=list)
    lacking: list[str] = field(default_factory=list)
    landed_though_failed: list[str] = field(default_factory=list)


def _write_and_check(
    rig: Rig, name: str, value: Any, expected: dict[str, Any], tally: Tally
) -> None:
    """One put (PVA; CA with callback for bits), then what the PLC holds:
    the written symbol has the value if the put succeeded and not if it
    failed; every other output is as it was."""
    symbol = OUTPUTS[name]
    answer = "(PVA put answered)"
    if isinstance(value, bool):
        answer = _put_with_callback(rig, name, "1" if value else "0")
        status = _put_status(answer)
    else:
        # completed once the record has processed: its alarm is the verdict
        rig.context.put(rig.pv(name), value, timeout=10, wait=True)
        shown: Any = rig.context.get(rig.pv(name), timeout=10)
        alarm = shown.raw.alarm
        verdict = alarm.message if alarm.severity == INVALID else ""
        status = verdict if verdict in ("WRITE", "TIMEOUT") else ""
    if status == "TIMEOUT":
        # outcome unknown (neither the write nor its read back was answered
        # in time): the write may still land; the PLC decides, once settled
        time.sleep(1.0)
        tally.unknown += 1
        expected[symbol] = rig.sim.get_symbol(symbol)
    plc = _plc(rig)
    tally.history.append(f"{name}={value!r}: {status or 'done'}")
    if status == "TIMEOUT":
        pass
    elif not status:
        tally.done += 1
        expected[symbol] = value
        if plc[symbol] != value:
            tally.lacking.append(
                f"{symbol}={value!r}, PLC holds {plc[symbol]!r}; the put's "
                f"answer: {answer.splitlines()[-1]!r}; before: {tally.history[-5:]}"
            )
    else:
        tally.failed += 1
        if plc[symbol] != expected[symbol]:
            tally.landed_though_failed.append(f"{symbol}={plc[symbol]!r}")
            expected[symbol] = plc[symbol]
    for other, held in expected.items():
        if other != symbol and plc[other] != held:
            tally.astray.append(
                f"{name}={value!r} -> {other}: {held!r} -> {plc[other]!r} "
                f"(puts before: {tally.history[-6:-1]})"
            )
            expected[other] = plc[other]


@pytest.mark.slow
def test_online_changes_never_misdirect_reads_or_writes(rig: Rig) -> None:
    """60 online changes (offsets move, old handles fail with 0x711), each
    followed by 1-3 puts at random moments within the first second, a third
    of them within the first poll cycle after the change; after every put
    the PLC is read: the put symbol holds the value if and only if the put
    succeeded, every other output is untouched, and every put succeeded
    (its symbol is still there: held through the change, then sent). Pinned
    inputs (and the master's slave count) are watched on PVA all along: no
    update without an alarm shows another value.
    """
    draw = random.Random(11)
    for symbol, value in PINNED.values():
        rig.sim.set_symbol(symbol, value)
    monitors = Monitors()
    watched = [*PINNED, SLAVE_COUNT]
    subscriptions = [
        rig.context.monitor(rig.pv(n), monitors.callback(n)) for n in watched
    ]
    try:
        assert wait_for(
            lambda: all(
                monitors.valid_values(n)[-1:] == [PINNED[n][1]] for n in PINNED
            ),
            10,
        )
        monitors.forget()  # from here on, only the pinned values are right
        _log(rig)
        expected = _plc(rig)
        tally = Tally()
        changes = 60
        for _ in range(changes):
            rig.sim.add_fault("online_change")
            for _ in range(draw.randint(1, 3)):
                # 0 to 50 ms: within the first poll cycle (20 Hz) after it
                time.sleep(draw.choice([0.0, 0.0, 0.01, 0.03, 0.05, 0.15, 0.4, 0.8]))
                name = draw.choice(list(OUTPUTS))
                value = _another(expected[OUTPUTS[name]], draw)
                _write_and_check(rig, name, value, expected, tally)
        assert rig.all_back()
        time.sleep(0.5)
    finally:
        for subscription in subscriptions:
            subscription.close()
    resyncs = int(rig.root("Resyncs") or 0)
    reconnects = int(rig.root("Reconnects") or 0)
    log = _log(rig)
    refusals = [line for line in log if " failed: " in line and "write of" in line]
    held = [line for line in log if "sent again after resolving" in line]
    wrong = {
        n: sorted({v for v in monitors.valid_values(n) if v != PINNED[n][1]})
        for n in PINNED
    }
    slave_counts = set(monitors.valid_values(SLAVE_COUNT))
    alarmed = sum(monitors.count(n) - len(monitors.valid_values(n)) for n in watched)
    untruthful = [
        text
        for name, symbol in OUTPUTS.items()
        if not (verdict := _truthful(rig, name, symbol))[0]
        for text in [f"{name}: {verdict[1]}"]
    ]
    print(
        f"\n{changes} online changes, {resyncs} resyncs, {reconnects} "
        "reconnects: "
        f"{tally.done} writes done, {tally.failed} failed, "
        f"{tally.unknown} of unknown outcome, {len(held)} held through a "
        f"change and sent again; {alarmed} alarmed updates of the watched PVs"
    )

    assert tally.lacking == []  # first: a put booked as done wrongly shows here
    assert tally.astray == []
    assert tally.landed_though_failed == []
    assert wrong == {n: [] for n in PINNED}
    assert slave_counts == {24}
    assert untruthful == []
    # every symbol is still there after each change: every put lands (a put
    # refused by the change is held until the handles are new, then sent),
    # but for those refused while the target was lost (a probe unanswered
    # on a loaded host): no put fails because of the online change
    assert tally.failed == len(refusals), refusals
    assert [line for line in refusals if "target not connected" not in line] == []
    assert tally.done >= 100
    assert held  # puts did meet a change: the hold path ran, and delivered
    assert alarmed > 0  # reads by old handles did fail, and alarmed


def test_a_device_port_without_symbol_version_resyncs_on_invalid_handles(
    tmp_path: Path,
) -> None:
    """Where the device port does not answer 0xF008 (older TwinCAT; whether a
    real one does is unconfirmed) the supervisor sees no online change: the
    handles failing with 0x711 are the only sign, and suffice."""
    chain = yaml.safe_load(DEMO_CHAIN.read_text(encoding="utf-8"))
    chain["system"]["symbol_version_on_device_port"] = False
    chain_file = tmp_path / "chain.yaml"
    chain_file.write_text(yaml.safe_dump(chain), encoding="utf-8")
    name, symbol = "ETH1:RIO21:MOD22:CH1:ValueRaw", f"{STANDARD} 1.Value"
    served = served_ioc("OLD", chain_file, lambda s, p: _config(tmp_path, s, p))
    with served as (sim, ioc):
        rig = Rig(sim, ioc, None)  # type: ignore[arg-type]
        assert rig.all_back(60)
        version = rig.root("SymbolVersion")
        sim.set_symbol(symbol, 1212)
        assert wait_for(lambda: caget(ioc, ioc.pv(name)).get(ioc.pv(name)) == "1212")
        resyncs = int(rig.root("Resyncs"))
        sim.add_fault("online_change")
        sim.set_symbol(symbol, 3434)
        follows = wait_for(
            lambda: caget(ioc, ioc.pv(name)).get(ioc.pv(name)) == "3434", 10
        )
        # statistics are posted once a second: wait for the count to follow
        resynced = wait_for(lambda: int(rig.root("Resyncs")) > resyncs, 5)
        back = rig.all_back()

    assert version == "-1"  # the IOC never learns a symbol version here
    assert follows and resynced and back
