"""What an output's setpoint shows: what was written, or what the PLC holds.

An output has a setpoint (the CA out record and the PVA setpoint PV) and a
readback (`_RBV`: what the PLC holds, polled). A setpoint may never show,
without an alarm, a value the PLC does not hold:

- a write that reached the PLC: both setpoints, CA and PVA, show the value
  (whichever protocol wrote it), no alarm of their own;
- a write that did not (refused, target away, an invalid handle, a value the
  type cannot hold): both show the value asked for, INVALID/WRITE, until a
  later write succeeds (the readback shows what the PLC holds meanwhile);
- a write whose outcome is unknown (no answer in time, the link lost while
  it was in flight) may have landed: the write path reads it back as soon
  as the target answers (at once, or after the reconnect) and the readback
  decides (written or failed); meanwhile INVALID/TIMEOUT ("outcome
  unknown");
- at start, and after every reconnect and online change, INVALID/UDF until
  the first readback, which the setpoint then takes over; except a setpoint
  whose last write failed: it keeps INVALID/WRITE through resyncs and
  readbacks (a resync and its first readback can land between a refused put
  and the put's answer to the client, which must see the put fail), and one
  whose last write's outcome is unknown keeps INVALID/TIMEOUT until its
  read back decides.

The alarms themselves are `Health`'s (setpoint problems); this decides which.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Any, Final

from fastcs.attributes import AttrR

from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.fastcs_adapter import records_of
from fastcs_ethercat.ioc.health import Health

logger = logging.getLogger(__name__)

WAITING: Final = "waiting for the value the PLC holds"


class Setpoints:
    """The setpoints of one master's outputs.

    What a setpoint shows is decided at once, before its value is shown: a
    resync's `follow` or a readback that lands meanwhile sees the decision,
    so a refused write stays refused; its alarm is shown after the value,
    once the put under way (if any) has been handled by FastCS, whose own
    verdict on the record is then raised to the IOC's.
    """

    def __init__(self, health: Health) -> None:
        self.health = health

    def follow(self, attributes: Iterable[AttrR[Any, Any]]) -> None:
        """Take over what these outputs' setpoints show from now (once their
        PVs are served): each waits for the PLC's value."""
        for attribute in attributes:
            status = self.health.setpoint_status(attribute)
            if status in (Status.WRITE, Status.TIMEOUT):
                continue  # until a later write succeeds, or the readback decides
            self.health.setpoint_problem(attribute, Status.UDF, WAITING)
            self.health.show_setpoint_soon(attribute)
            self.health.watch_value(attribute, self._from_plc)

    async def _from_plc(self, attribute: AttrR[Any, Any], value: Any) -> None:
        await self._show(attribute, value)

    async def written(self, attribute: AttrR[Any, Any], value: Any) -> None:
        """The PLC took `value`."""
        self.health.unwatch_value(attribute)
        await self._show(attribute, value)

    async def failed(self, attribute: AttrR[Any, Any], value: Any, why: str) -> None:
        """`value` did not reach the PLC."""
        self.health.unwatch_value(attribute)
        await self._show(attribute, value, Status.WRITE, why)

    async def unknown(self, attribute: AttrR[Any, Any], value: Any, why: str) -> None:
        """A write of `value` whose outcome is unknown (not answered, nor a
        read back): INVALID/TIMEOUT until the write path has read it back
        once the target answers again (then `written` or `failed`)."""
        self.health.unwatch_value(attribute)
        await self._show(attribute, value, Status.TIMEOUT, why)

    async def _show(
        self,
        attribute: AttrR[Any, Any],
        value: Any,
        problem: Status | None = None,
        why: str = "",
    ) -> None:
        """Decide now (`problem`, or none), then show `value` on both
        setpoints, then their alarm (showing the value clears it on PVA)."""
        if problem is None:
            self.health.setpoint_fine(attribute)
        else:
            self.health.setpoint_problem(attribute, problem, why)
        records_of(attribute).show_setpoint(value)
        self.health.show_setpoint_soon(attribute)
