"""Post polled values to their PVs, every value of one poll cycle at one time.

`AttrR.update()` of FastCS 0.14.4 lets each transport stamp a value with the
time its callback runs and costs ~120 µs (two tasks, reprs for its tracer).
A poll cycle's values were all read by one ADS request, so they should all
carry that request's time, and a cycle of thousands of changes must not cost
a core. `Publisher.publish` therefore sets the attribute's value as
`update()` would and posts straight to the CA in record (kept on device time,
its processing queued without giving up the GIL) and the PVA read PV (value,
NO_ALARM and the timestamp), then calls any other callback; `fastcs_hooks`
knows how.

Alarms are not sticky here either: a published value carries NO_ALARM, as
one from `update()` does (see `ioc.alarms`, `ioc.health`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

from fastcs.attributes import AttrR
from fastcs.datatypes import Bool, Enum, Float, Int, String, Waveform
from fastcs.transports.epics.ca.util import cast_to_epics_type
from fastcs.transports.epics.pva.types import cast_to_p4p_value

from fastcs_ethercat.ioc import fastcs_hooks
from fastcs_ethercat.ioc.fastcs_hooks import ReadRoute

_NO_ALARM: Final = {"severity": 0, "status": 0, "message": ""}
_SCALARS: Final = (Int, Float, Bool, String)


def pva_time(stamp: float) -> dict[str, int]:
    """The PVA timeStamp fields of a time.time() value."""
    seconds = int(stamp)
    return {"secondsPastEpoch": seconds, "nanoseconds": int((stamp - seconds) * 1e9)}


class Publisher:
    """Publishes values of attributes the IOC keeps, once the transports serve.

    Until `start()` (the transports' PVs exist only from when they serve),
    values go through `update()`. The first value published for an attribute
    is posted even when it equals the attribute's value, so its records start
    on device time with a real timestamp.
    """

    def __init__(self) -> None:
        self.started = False
        self._routes: dict[int, _Route] = {}

    def start(self) -> None:
        self.started = True

    async def publish(
        self, attribute: AttrR[Any, Any], value: Any, stamp: float | None = None
    ) -> bool:
        """Post `value` (if new) at `stamp` (now if None); True if posted."""
        datatype = attribute.datatype
        validated = datatype.validate(value)
        if not self.started:
            if datatype.equal(attribute.get(), validated):
                return False
            await attribute.update(validated)
            return True
        route = self._routes.get(id(attribute))
        if route is None:
            route = self._routes[id(attribute)] = _Route.of(attribute)
        elif datatype.equal(attribute.get(), validated):
            return False
        await route.post(validated, stamp or time.time())
        return True


@dataclass
class _Route:
    """One attribute and where its values go."""

    attribute: AttrR[Any, Any]
    read: ReadRoute
    set_ca: Callable[[Any, float], None] | None

    @classmethod
    def of(cls, attribute: AttrR[Any, Any]) -> _Route:
        read = fastcs_hooks.read_route(attribute)
        set_ca = None
        if read.ca_in is not None:
            fastcs_hooks.use_device_time(read.ca_in)
            set_ca = fastcs_hooks.in_record_setter(read.ca_in)
        return cls(attribute, read, set_ca)

    async def post(self, value: Any, stamp: float) -> None:
        attribute = self.attribute
        fastcs_hooks.store_value(attribute, value)
        await fastcs_hooks.init_setpoint(attribute, value)
        if self.set_ca is not None:
            self.set_ca(cast_to_epics_type(attribute.datatype, value), stamp)
        if self.read.pva_read is not None:
            _post_pva(self.read.pva_read, attribute, value, stamp)
        for callback in self.read.others:
            await callback(value)


def _post_pva(pv: Any, attribute: AttrR[Any, Any], value: Any, stamp: float) -> None:
    """The value, NO_ALARM and `stamp`, in the form FastCS's PV type takes."""
    datatype = attribute.datatype
    if isinstance(datatype, _SCALARS):
        pv.post({"value": value, "alarm": _NO_ALARM, "timeStamp": pva_time(stamp)})
    elif isinstance(datatype, Enum | Waveform):
        pv.post(
            cast_to_p4p_value(attribute, value),
            timestamp=stamp,
            severity=0,
            message="",
        )
    else:
        pv.post(cast_to_p4p_value(attribute, value))
