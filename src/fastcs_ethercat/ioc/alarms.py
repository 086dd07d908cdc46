"""Put an attribute's PVs into alarm, or out of it (its records: CA and PVA
serve the same ones).

FastCS 0.14 has no alarm API for attributes: `fastcs_adapter` reaches the
records its transport made and gives them a new alarm with the same value
(in records raised and processed with their value, so their own limits and
links take part; out records made current without processing, which would
write to the PLC). The time of the alarm is the time it is shown.

Alarms are not sticky, as in an EPICS record: the next value published for
the attribute carries its own alarm again (`value_alarm`: NO_ALARM, or the
STATE alarm of a status bit that is set), and `ioc.health` holds values back
while an attribute is in alarm. Call from the IOC's event loop once the
transports serve; before that, whatever is not built yet is skipped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, Final

from fastcs.attributes import Attribute

from fastcs_ethercat.ioc.datatypes import severity_table
from fastcs_ethercat.ioc.fastcs_adapter import Parts, records_of


class Severity(IntEnum):
    """EPICS alarm severity (menuAlarmSevr), the same numbers on CA and PVA."""

    NO_ALARM = 0
    MINOR = 1
    MAJOR = 2
    INVALID = 3


class Status(IntEnum):
    """EPICS alarm status (menuAlarmStat): what CA clients see as STAT."""

    NO_ALARM = 0
    READ = 1
    WRITE = 2
    HIHI = 3
    HIGH = 4
    LOLO = 5
    LOW = 6
    STATE = 7
    COS = 8
    COMM = 9
    TIMEOUT = 10
    HWLIMIT = 11
    CALC = 12
    SCAN = 13
    LINK = 14
    SOFT = 15
    BAD_SUB = 16
    UDF = 17
    DISABLE = 18
    SIMM = 19
    READ_ACCESS = 20
    WRITE_ACCESS = 21


@dataclass(frozen=True)
class AlarmState:
    """One alarm: severity, status and a text for the log."""

    severity: Severity
    status: Status
    message: str = ""


NO_ALARM: Final = AlarmState(Severity.NO_ALARM, Status.NO_ALARM)
VALUE_STATUS: Final = Status.STATE
"""The status of an alarm a value carries itself (a set Error bit, a slave
not in OP): EPICS' STATE, as a bi record's OSV gives it."""


def state_alarm(severity: int) -> tuple[int, int]:
    """(severity, status) of a value whose state has `severity`."""
    return (severity, VALUE_STATUS) if severity else (0, 0)


def value_alarm(attribute: Attribute[Any, Any]) -> AlarmState:
    """The alarm of the attribute's current value by itself: NO_ALARM unless
    its datatype says the value is an alarm state (`datatypes.ValueAlarms`)."""
    severity_of = severity_table(attribute.datatype)
    if severity_of is None or not hasattr(attribute, "get"):
        return NO_ALARM
    severity = severity_of(attribute.get())  # pyright: ignore[reportAttributeAccessIssue]
    return AlarmState(Severity(severity), VALUE_STATUS) if severity else NO_ALARM


def publish_alarm(
    attribute: Attribute[Any, Any], state: AlarmState, parts: Parts = Parts.ALL
) -> int:
    """Publish `state` on the records of `attribute` (of `parts`: its
    readback, its setpoint or both). The record's alarm message (AMSG, the
    message PVA clients see) is `STATUS: text`, so they see the status too."""
    message = f"{state.status.name}: {state.message}" if state.message else ""
    return records_of(attribute).publish_alarm(
        int(state.severity), int(state.status), message, parts
    )


def hold_setpoint(attribute: Attribute[Any, Any]) -> Callable[[], None]:
    """Lock `attribute`'s setpoint record (EPICS's `dbScanLock`: nothing
    else processes it meanwhile); the call that unlocks it."""
    return records_of(attribute).hold_setpoint()
