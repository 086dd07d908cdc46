"""Post polled values to their PVs, every value of one poll cycle at one time.

A poll cycle's values were all read by one ADS request, so they all carry
that request's time, and only values that changed are posted. The posting
itself (`Update(value, timestamp)` straight to the CA record and the PVA PV)
is `fastcs_adapter`'s until FastCS releases its own `Update`.

Alarms are not sticky here either: a published value carries its own alarm,
NO_ALARM unless its datatype makes it an alarm state (a set Error bit: the
severity from the datatype's table, status STATE; see `ioc.alarms`,
`ioc.health`).
"""

from __future__ import annotations

import time
from typing import Any

from fastcs.attributes import AttrR

from fastcs_ethercat.ioc.alarms import state_alarm
from fastcs_ethercat.ioc.datatypes import severity_table
from fastcs_ethercat.ioc.fastcs_adapter import Update, ValueRoute

_Route = tuple[ValueRoute, Any]
"""An attribute's route and its datatype's severity table (None: no alarms)."""


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
        found = self._routes.get(id(attribute))
        if found is None:
            found = (ValueRoute(attribute), severity_table(datatype))
            self._routes[id(attribute)] = found
        elif datatype.equal(attribute.get(), validated):
            return False
        route, severity_of = found
        if severity_of is None:
            await route.publish(Update(validated, stamp or time.time()))
        else:
            alarm = state_alarm(severity_of(validated))
            await route.publish(Update(validated, stamp or time.time(), *alarm))
        return True
