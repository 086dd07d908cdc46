"""Put an attribute's PVs into alarm, or out of it, on CA and PVA at once.

FastCS 0.14.4 has no alarm API for attributes, so this reaches the records and
PVs its transports made (through `fastcs_hooks`) and republishes the same
value with a new alarm:

- CA in records (`<Name>`, `<Name>_RBV`): softioc `set_alarm`, which processes
  the record with its held value, so monitors see the new SEVR/STAT;
- CA out records (`<Name>` of a writable attribute): alarm set without
  processing (processing an out record would write to the device), see
  `fastcs_hooks.set_out_record_alarm`;
- PVA: a post of only the `alarm` and `timeStamp` fields; the value stays.

Alarms are not sticky, as in an EPICS record: the next value FastCS publishes
for the attribute (`attribute.update()` with a changed value) carries
NO_ALARM again. So: set an alarm when a value becomes unknown and stop
updating that attribute; when it is known again, update it and call
`clear_alarm` (FastCS publishes nothing when the value did not change).

Call from the IOC's event loop once the transports serve (PVA PVs exist only
from then on); before that, whatever is not built yet is skipped.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, Final

import numpy as np
from fastcs.attributes import Attribute

from fastcs_ethercat.ioc.fastcs_hooks import (
    Endpoints,
    endpoints_of,
    set_out_record_alarm,
)
from fastcs_ethercat.ioc.publish import pva_time


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


class PvaStatus(IntEnum):
    """The coarser status of the PVA alarm_t structure."""

    NO_ALARM = 0
    DEVICE = 1
    DRIVER = 2
    RECORD = 3
    DB = 4
    CONF = 5
    UNDEFINED = 6
    CLIENT = 7


_DEVICE: Final = {
    Status.READ, Status.WRITE, Status.HIHI, Status.HIGH, Status.LOLO,
    Status.LOW, Status.STATE, Status.COS, Status.HWLIMIT,
}  # fmt: skip
_DRIVER: Final = {Status.COMM, Status.TIMEOUT, Status.UDF}
_RECORD: Final = {Status.CALC, Status.SCAN, Status.LINK, Status.SOFT, Status.BAD_SUB}
_DB: Final = {Status.DISABLE, Status.SIMM, Status.READ_ACCESS, Status.WRITE_ACCESS}


def pva_status(status: Status) -> PvaStatus:
    """The PVA status for a CA status, grouped as the IOC's QSRV groups them."""
    if status is Status.NO_ALARM:
        return PvaStatus.NO_ALARM
    for group, pva in (
        (_DEVICE, PvaStatus.DEVICE),
        (_DRIVER, PvaStatus.DRIVER),
        (_RECORD, PvaStatus.RECORD),
        (_DB, PvaStatus.DB),
    ):
        if status in group:
            return pva
    return PvaStatus.UNDEFINED


@dataclass(frozen=True)
class AlarmState:
    """One alarm: severity, CA status and a text for PVA clients."""

    severity: Severity
    status: Status
    message: str = ""

    def pva_message(self) -> str:
        """The CA status name (PVA has no such detail), then the text."""
        if self.status is Status.NO_ALARM:
            return self.message
        return (
            f"{self.status.name}: {self.message}" if self.message else self.status.name
        )


NO_ALARM: Final = AlarmState(Severity.NO_ALARM, Status.NO_ALARM)


def set_alarm(
    attribute: Attribute[Any, Any],
    severity: Severity,
    status: Status,
    message: str = "",
) -> int:
    """Raise `attribute`'s PVs to this alarm, value unchanged; PVs reached."""
    return publish_alarm(attribute, AlarmState(severity, status, message))


def clear_alarm(attribute: Attribute[Any, Any]) -> int:
    """Return `attribute`'s PVs to NO_ALARM, value unchanged; PVs reached."""
    return publish_alarm(attribute, NO_ALARM)


def set_alarms(
    attributes: Iterable[Attribute[Any, Any]],
    severity: Severity,
    status: Status,
    message: str = "",
) -> int:
    """`set_alarm` for many attributes (a whole target or terminal)."""
    state = AlarmState(severity, status, message)
    return sum(publish_alarm(attribute, state) for attribute in attributes)


def clear_alarms(attributes: Iterable[Attribute[Any, Any]]) -> int:
    """`clear_alarm` for many attributes."""
    return sum(publish_alarm(attribute, NO_ALARM) for attribute in attributes)


def publish_alarm(attribute: Attribute[Any, Any], state: AlarmState) -> int:
    """Publish `state` on every CA record and PVA PV of `attribute`."""
    return publish_to(endpoints_of(attribute), state)


def publish_to(endpoints: Endpoints, state: AlarmState) -> int:
    """Publish `state` on the records and PVs in `endpoints`; how many."""
    reached = 0
    if endpoints.ca_in is not None:
        endpoints.ca_in.set_alarm(  # the time too: the record may be on device time
            int(state.severity), int(state.status), timestamp=time.time()
        )
        reached += 1
    if endpoints.ca_out is not None:
        set_out_record_alarm(endpoints.ca_out, int(state.severity), int(state.status))
        reached += 1
    for pv in (endpoints.pva_read, endpoints.pva_write):
        if pv is not None:
            _post_pva_alarm(pv, state)
            reached += 1
    return reached


def _post_pva_alarm(pv: Any, state: AlarmState) -> None:
    """Post only alarm and time, so the value stays as FastCS last posted it."""
    now = time.time()
    current = pv.current()
    if isinstance(current, np.ndarray):
        # NTNDArray (a FastCS Waveform) wraps only arrays; its alarm has no status.
        pv.post(
            current,
            severity=int(state.severity),
            message=state.pva_message(),
            timestamp=now,
        )
        return
    pv.post(
        {
            "alarm": {
                "severity": int(state.severity),
                "status": int(pva_status(state.status)),
                "message": state.pva_message(),
            },
            "timeStamp": pva_time(now),
        }
    )
