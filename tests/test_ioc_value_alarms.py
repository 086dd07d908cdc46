"""Values that carry their own alarm, and values made from another one.

In process (no records: what reaches them, with its time, is
test_ioc_publish's): a status bit's severity goes with its value, a cleared
alarm goes back to the value's own severity, and a scaled value follows its
raw count in value and alarm (`Health.follow`).
"""

from __future__ import annotations

import enum
from typing import Any

import pytest
from fastcs.attributes import AttrR, AttrRW
from fastcs.datatypes import Bool, Int

from fastcs_ethercat.ioc.alarms import NO_ALARM, Severity, Status
from fastcs_ethercat.ioc.alarms import value_alarm as alarm_of_value
from fastcs_ethercat.ioc.attributes import to_engineering
from fastcs_ethercat.ioc.datatypes import (
    AlarmBool,
    AlarmEnum,
    AlarmInt,
    ExactFloat,
    alarm_enum,
    severity_table,
)
from fastcs_ethercat.ioc.health import COMM, READ, Health
from fastcs_ethercat.terminals.meaning import Scaling


class State(enum.Enum):
    INIT = "INIT"
    OP = "OP"


def test_alarm_datatypes_look_up_their_severity() -> None:
    error = AlarmBool(severities=(0, 2))
    limit = AlarmInt(min=0, max=3, set_severity=1)
    state = alarm_enum(State, {State.INIT: 2})

    assert [error.alarm_severity(v) for v in (False, True)] == [0, 2]
    assert [limit.alarm_severity(v) for v in (0, 1, 2, 3)] == [0, 1, 1, 1]
    assert isinstance(state, AlarmEnum)
    assert [state.alarm_severity(v) for v in State] == [2, 0]
    assert severity_table(Bool()) is None
    assert severity_table(error) is not None
    assert isinstance(error, Bool) and isinstance(limit, Int)  # FastCS records


async def test_a_set_error_bit_is_published_major_and_clears_with_it() -> None:
    health = Health()
    await health.publisher.start()
    error = AttrR(AlarmBool(severities=(0, 2)))

    await health.post(error, True)
    raised = alarm_of_value(error), health.publisher.posted
    await health.post(error, False)
    cleared = alarm_of_value(error), health.publisher.posted

    assert raised[1] == 1 and cleared[1] == 2  # each posted
    assert (raised[0].severity, raised[0].status) == (Severity.MAJOR, Status.STATE)
    assert cleared[0] == NO_ALARM


async def test_an_outage_ends_in_the_values_own_alarm_not_in_no_alarm() -> None:
    health = Health()
    await health.publisher.start()
    error = AttrR(AlarmBool(severities=(0, 2)))
    await health.post(error, True)

    health.mark_invalid([error], COMM, Status.COMM, "PLC lost")
    lost = health.is_invalid(error)
    await health.mark_ok([error], COMM)

    assert lost and not health.is_invalid(error)
    assert alarm_of_value(error).severity is Severity.MAJOR  # the bit is still set
    assert alarm_of_value(AttrR(Int())) == NO_ALARM


async def test_a_scaled_value_follows_its_raw_count() -> None:
    health = Health()
    await health.publisher.start()
    raw = AttrR(Int(min=-32768, max=32767))
    volts = AttrRW(ExactFloat(units="V", prec=4, min=-10.0003, max=10.0))
    health.follow(raw, volts, to_engineering(Scaling(10 / 32767, 0.0, "V")))

    await health.post(raw, 16384)
    first = (raw.get(), volts.get())
    health.mark_invalid([raw], READ, Status.READ, "0x705")
    both_invalid = (health.is_invalid(raw), health.is_invalid(volts))
    await health.post(raw, -32767)  # a fresh value ends a READ alarm
    after = (raw.get(), volts.get(), health.invalid_count)
    seen: list[tuple[Any, Any]] = []

    async def watch(attribute: Any, value: Any) -> None:  # as ioc.setpoints does
        seen.append((attribute, value))

    health.watch_value(volts, watch)  # an output's setpoint waits for the PLC
    await health.post(raw, 0)

    assert first[0] == 16384
    assert first[1] == pytest.approx(5.0002, abs=1e-4)
    assert both_invalid == (True, True)
    assert after[:2] == (-32767, pytest.approx(-10.0))
    assert after[2] == 0
    assert seen == [(volts, 0.0)]  # the PLC's value, in volts
