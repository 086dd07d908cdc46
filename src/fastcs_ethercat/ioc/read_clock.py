"""The time of the values being posted: `<prefix>:ReadTime`.

Every input record of the IOC takes its time from this record's TIME
(`TSEL "<prefix>:ReadTime.TIME"`, `ioc.database`). Before the values of an
ADS sum read are posted, the clock is set to that read's time (softioc's
`set(value, timestamp=...)` and a processing of the record, at once, in the
poster's thread); every record those values process takes that time, so a
poll cycle's values share one timestamp, the time they were read. Before
anything else is posted (an alarm, a value not read from the target) the
clock is set to the time of the posting.

Its value counts the times the clock was set.
"""

from __future__ import annotations

import time
from typing import Any, Final

from fastcs_ethercat.ioc.dbaccess import Record

CLOCK_SEGMENT: Final = "ReadTime"


def clock_name(prefix: str) -> str:
    """The clock record of the IOC serving under `prefix`."""
    return f"{prefix}:{CLOCK_SEGMENT}"


class ReadClock:
    """The clock record: made before the database loads, set once it serves."""

    def __init__(self, name: str, device: Any) -> None:
        self.name = name
        self.time = 0.0
        """The time the clock holds now (0: never set)."""
        self._device = device
        self._record: Record | None = None
        self._count = 0

    def set(self, seconds: float) -> None:
        """The records processed from now on take `seconds` as their time."""
        if seconds == self.time:
            return
        if self._record is None:
            self._record = Record(self.name)
        self._count = (self._count + 1) & 0x7FFFFFFF
        self._device.set(self._count, timestamp=seconds)
        self._record.process()
        self.time = seconds


_clock: ReadClock | None = None
"""This process's clock (softioc serves one IOC per process)."""


def make_clock(prefix: str) -> ReadClock:
    """The clock record of the IOC under `prefix` (softioc's Python device
    support, Passive: processed only when set), made before the database
    is loaded."""
    from softioc import builder

    global _clock
    name = clock_name(prefix)
    device = builder.longIn(
        name,
        SCAN="Passive",
        PINI="NO",
        TSE=-2,  # its time is the one `set` gives (device time)
        MDEL=0,
        DESC="Time of the values posted (every TSEL)",
        initial_value=0,
    )
    _clock = ReadClock(name, device)
    return _clock


def clock() -> ReadClock | None:
    """The clock, once made (None in a process that serves no database)."""
    return _clock


def set_clock(seconds: float | None = None) -> None:
    """Records processed from now on take `seconds` as their time (now if
    None); nothing before the clock is made."""
    if _clock is not None:
        _clock.set(time.time() if seconds is None else seconds)
