"""What an output's setpoint shows, in-process: an `AttrRW` (no database,
no target), `Health` and `Setpoints` deciding its readback's and setpoint's
value and alarm (the records that show them are the end-to-end tests':
softioc serves one database per process, so here the setpoint record is a
stand-in that keeps the value shown); and the supervisor's resync on
request (a master whose handles went invalid)."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from fastcs.attributes import Attribute, AttrRW
from fastcs.datatypes import Int

from fastcs_ethercat.ads.constants import AdsState
from fastcs_ethercat.ioc import setpoints as setpoints_module
from fastcs_ethercat.ioc.alarms import AlarmState, Severity, Status, value_alarm
from fastcs_ethercat.ioc.health import COMM, Health
from fastcs_ethercat.ioc.setpoints import WAITING, Setpoints
from fastcs_ethercat.ioc.supervisor import Probe, Supervisor


class SetpointRecord:
    """Stands in for an output's records: keeps the value shown on the
    setpoint (`AttributeRecords.show_setpoint`)."""

    def __init__(self) -> None:
        self.value: Any = 0

    def show_setpoint(self, value: Any) -> None:
        self.value = value


SHOWN: dict[int, SetpointRecord] = {}


@pytest.fixture(autouse=True)
def setpoint_records(monkeypatch: pytest.MonkeyPatch) -> None:
    def records_of(attribute: Attribute[Any, Any]) -> SetpointRecord:
        return SHOWN.setdefault(id(attribute), SetpointRecord())

    SHOWN.clear()
    monkeypatch.setattr(setpoints_module, "records_of", records_of)


class Output:
    """An output attribute, and what its readback and setpoint show as
    `Health` decides it: the setpoint's value as shown on its record, the
    alarms from `Health`."""

    def __init__(self, health: Health) -> None:
        self.health = health
        self.attribute = AttrRW(Int(), initial_value=0)

    @property
    def setpoint(self) -> Any:
        shown = SHOWN.get(id(self.attribute))
        return 0 if shown is None else shown.value

    def shown(self) -> tuple[tuple[Any, int], tuple[Any, int, str]]:
        """(value, severity) of the readback, then (value, severity,
        "STATUS: message") of the setpoint."""
        attribute, health = self.attribute, self.health
        severity = value_alarm(attribute).severity
        if health.is_invalid(attribute):
            severity = Severity.INVALID
        setpoint = health.setpoint_alarm(attribute)
        return (
            (attribute.get(), int(severity)),
            (self.setpoint, int(setpoint.severity), _text(setpoint)),
        )


def _text(state: AlarmState) -> str:
    """What a PVA client read as the message: the status, then the text."""
    if not state.severity:
        return ""
    name = state.status.name
    return f"{name}: {state.message}" if state.message else name


async def _settled() -> None:
    """Let the alarms published `call_soon` (after a put's answer) land."""
    await asyncio.sleep(0)
    await asyncio.sleep(0)


async def test_a_failed_write_alarms_the_setpoint_only_until_a_write_succeeds() -> None:
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    await health.post(output.attribute, 5)

    await setpoints.failed(output.attribute, 9, "not written: refused")
    await _settled()
    failed = output.shown()
    await health.post(output.attribute, 6)  # the PLC's value moves on
    moved = output.shown()
    await setpoints.written(output.attribute, 7)
    await _settled()

    assert failed == ((5, 0), (9, 3, "WRITE: not written: refused"))
    assert moved == ((6, 0), (9, 3, "WRITE: not written: refused"))
    assert output.shown()[1] == (7, 0, "")


async def test_the_setpoints_own_problem_outlasts_the_readbacks() -> None:
    """The target goes (COMM on both), a write is refused meanwhile (WRITE on
    the setpoint), the target returns (the readback is valid again): the
    setpoint keeps its own alarm; once that goes it shows no alarm."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await health.post(output.attribute, 0)
    health.mark_invalid([output.attribute], COMM, Status.COMM, "lost")
    lost = output.shown()
    await setpoints.failed(output.attribute, 3, "not written: target away")
    await _settled()
    await health.post(output.attribute, 1)  # a fresh value: COMM is gone
    back = output.shown()
    health.setpoint_fine(output.attribute)
    health.show_setpoint(output.attribute)

    assert lost[0][1] == 3
    assert lost[1][1:] == (3, "COMM: lost")
    assert back == ((1, 0), (3, 3, "WRITE: not written: target away"))
    assert output.shown()[1] == (3, 0, "")


async def test_a_setpoint_waits_for_and_takes_the_plcs_value() -> None:
    """After start, a reconnect or an online change: UDF until the first
    value, which the setpoint then shows; also one held while in alarm."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await _settled()
    waiting = output.shown()[1]
    await health.post(output.attribute, 42)
    await _settled()
    taken = output.shown()[1]
    health.mark_invalid([output.attribute], "slave", Status.STATE, "not in OP")
    setpoints.follow([output.attribute])
    await health.post(output.attribute, 43)  # held: the terminal is not in OP
    await _settled()
    held = output.shown()[1]
    await health.mark_ok([output.attribute], "slave")
    await _settled()

    assert waiting == (0, 3, f"UDF: {WAITING}")
    assert taken == (42, 0, "")
    assert held == (42, 3, f"UDF: {WAITING}")
    assert output.shown() == ((43, 0), (43, 0, ""))


async def test_a_setpoint_takes_the_plcs_value_from_a_poll_cycles_batch() -> None:
    """Polled values come as one batch per cycle (`Health.post_batch`): the
    setpoint waiting for the PLC's value takes it from there too."""
    health = Health()
    output = Output(health)
    Setpoints(health).follow([output.attribute])
    await _settled()
    published = await health.post_batch([(output.attribute, 42)])
    await _settled()

    assert published.failures == []
    assert output.shown() == ((42, 0), (42, 0, ""))


async def test_a_resync_does_not_turn_a_refused_write_into_waiting() -> None:
    """A put refused while the IOC resyncs, then the resync's `follow` before
    the put's answer reaches the client (seen in the online-change test): the
    setpoint keeps INVALID/WRITE (the client must see the put fail, not UDF
    nor the first readback's value without an alarm) until a write succeeds."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await health.post(output.attribute, 5)
    await setpoints.failed(output.attribute, 9, "not written: target away")
    setpoints.follow([output.attribute])  # the resync ends
    await _settled()
    answered = output.shown()[1]
    await health.post(output.attribute, 6)  # the first readback after it
    await _settled()

    after_readback = output.shown()[1]
    await setpoints.written(output.attribute, 7)
    await _settled()

    assert answered == (9, 3, "WRITE: not written: target away")
    assert after_readback == (9, 3, "WRITE: not written: target away")
    assert output.shown()[1] == (7, 0, "")


async def test_a_resync_while_a_refused_write_is_being_shown_keeps_it_refused() -> None:
    """The race the online-change test met under load: the resync's `follow`
    runs while `failed` is still showing the refused value (it awaits FastCS's
    setpoint callbacks), then the first readback lands before the put's
    answer. The setpoint must stay INVALID/WRITE with the value asked for,
    not take the readback's value without an alarm (`caput -c` read it as a
    put that was done)."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await health.post(output.attribute, 5)
    await _settled()
    refusing = asyncio.create_task(
        setpoints.failed(output.attribute, 9, "not written: target away")
    )
    await asyncio.sleep(0)  # `failed` is inside its sync of the setpoints
    setpoints.follow([output.attribute])  # the resync ends meanwhile
    await refusing
    await health.post(output.attribute, 5)  # the first readback after it
    await _settled()

    assert output.shown()[1] == (9, 3, "WRITE: not written: target away")


async def test_a_readback_being_shown_does_not_undo_a_refused_write() -> None:
    """The other order: the setpoint is taking the first readback after a
    resync (awaiting FastCS's setpoint callbacks) when a write is refused:
    the refusal is what the setpoint ends up showing."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    taking = asyncio.create_task(health.post(output.attribute, 5))
    await asyncio.sleep(0)  # the readback's value is being shown
    await setpoints.failed(output.attribute, 9, "not written: target away")
    await taking
    await _settled()

    assert output.shown()[1] == (9, 3, "WRITE: not written: target away")


async def test_an_unknown_outcome_waits_for_the_write_paths_read_back() -> None:
    """Neither a poll's readback nor a resync's `follow` ends an unknown
    outcome: the write path reads the symbol back and decides."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])  # polling started
    await setpoints.unknown(output.attribute, 8, "outcome unknown: no answer")
    await _settled()
    unknown = output.shown()[1]
    await health.post(output.attribute, 2)  # a poll, before the read back
    setpoints.follow([output.attribute])  # a resync
    await _settled()
    kept = output.shown()[1]
    await setpoints.failed(output.attribute, 8, "not written: the PLC holds 2")
    await _settled()

    assert unknown == (8, 3, "TIMEOUT: outcome unknown: no answer")
    assert kept == unknown
    assert output.shown()[1] == (8, 3, "WRITE: not written: the PLC holds 2")


async def test_a_refused_write_ends_when_the_plc_holds_its_value_after_all() -> None:
    """Issue 25: a put of 9 refused while the target was away, the PLC at 9
    all along: once the target is back, the readback of 9 ends the WRITE
    alarm (the setpoint equals the PLC); a readback of another value did
    not."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await health.post(output.attribute, 9)
    health.mark_invalid([output.attribute], COMM, Status.COMM, "lost")
    await setpoints.failed(output.attribute, 9, "not written: target away")
    await _settled()
    refused = output.shown()[1]
    setpoints.follow([output.attribute])  # the reconnect's resync
    await health.post(output.attribute, 8)  # another value first: still refused
    await _settled()
    other = output.shown()[1]
    await health.post(output.attribute, 9)
    await _settled()

    assert refused == (9, 3, "WRITE: not written: target away")
    assert other == (9, 3, "WRITE: not written: target away")
    assert output.shown() == ((9, 0), (9, 0, ""))


async def test_a_refused_write_asks_for_a_fresh_readback_after_its_answer() -> None:
    """The PLC already holds the refused value and nothing changes (the
    poller hands on changes only): the setpoint asks for a fresh readback
    once the put's answer has gone out; a readback landing before that (a
    resync's first, between the refusal and the answer) leaves the refusal
    for the client to see."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await health.post(output.attribute, 9)
    rereads: list[str] = []
    await setpoints.failed(
        output.attribute, 9, "not written: refused", lambda: rereads.append("asked")
    )
    await health.post(output.attribute, 9)  # before the answer went out
    before_answer = (output.shown()[1], list(rereads))
    await _settled()
    answered = (output.shown()[1], list(rereads))
    await health.post(output.attribute, 9)  # the fresh readback asked for
    await _settled()

    assert before_answer == ((9, 3, "WRITE: not written: refused"), [])
    assert answered == ((9, 3, "WRITE: not written: refused"), ["asked"])
    assert output.shown()[1] == (9, 0, "")


async def test_a_later_verdict_outranks_a_refusals_readback() -> None:
    """A refused put of 9, then a put of 7 that succeeds: a readback of 9
    (the PLC before the second put's value showed) no longer speaks for the
    setpoint; nor does one for a refusal superseded by another refusal."""
    health = Health()
    output = Output(health)
    setpoints = Setpoints(health)
    setpoints.follow([output.attribute])
    await setpoints.failed(output.attribute, 9, "not written: refused")
    await setpoints.written(output.attribute, 7)
    await _settled()
    await health.post(output.attribute, 9)
    await _settled()
    after_written = output.shown()[1]
    await setpoints.failed(output.attribute, 4, "not written: refused")
    await _settled()
    await setpoints.failed(output.attribute, 5, "not written: refused again")
    await _settled()
    await health.post(output.attribute, 4)
    await _settled()

    assert after_written == (7, 0, "")
    assert output.shown()[1] == (5, 3, "WRITE: not written: refused again")


class Link:
    """Counts what the supervisor asks of the IOC."""

    def __init__(self) -> None:
        self.resyncs: list[str] = []

    async def lost(self, reason: str) -> None:
        raise AssertionError(reason)

    async def stopped(self, ads_state: int) -> None:
        raise AssertionError(ads_state)

    async def reconnect(self) -> int:
        raise AssertionError("no reconnect")

    async def resync(self, why: str) -> int:
        self.resyncs.append(why)
        return 7


async def test_a_master_can_ask_for_a_resync_at_most_once_a_second() -> None:
    """The device port may not answer 0xF008: a handle that went invalid is
    then the only sign of an online change."""

    async def probe() -> Probe:
        return Probe(int(AdsState.RUN), 7)

    link = Link()
    supervisor = Supervisor(probe, link, 7)
    await supervisor.step()
    supervisor.request_resync("symbol handles invalid")
    supervisor.request_resync("a write's handle invalid")
    await supervisor.step()
    await supervisor.step()
    supervisor.request_resync("again at once")
    await supervisor.step()
    deferred = list(link.resyncs)
    supervisor._last_requested -= 1.0  # a second later
    await supervisor.step()

    assert deferred == ["symbol handles invalid"]
    assert link.resyncs == ["symbol handles invalid", "again at once"]
