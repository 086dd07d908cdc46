"""What an output's setpoint shows: what was written, or what the PLC holds.

An output has a setpoint (the CA out record and the PVA setpoint PV) and a
readback (`_RBV`: what the PLC holds, polled). A setpoint may never show,
without an alarm, a value the PLC does not hold:

- a write that reached the PLC: both setpoints, CA and PVA, show the value
  (whichever protocol wrote it), no alarm of their own;
- a write that did not (refused, target away, an invalid handle, a value the
  type cannot hold): both show the value asked for, INVALID/WRITE, until a
  later write succeeds, or until a readback shows the PLC holds that value
  after all (the readback shows what the PLC holds meanwhile);
- a write whose outcome is unknown (no answer in time, the link lost while
  it was in flight) may have landed: the write path reads it back as soon
  as the target answers (at once, or after the reconnect) and the readback
  decides (written or failed); meanwhile INVALID/TIMEOUT ("outcome
  unknown");
- at start, and after every reconnect and online change, INVALID/UDF until
  the first readback, which the setpoint then takes over; except a setpoint
  whose last write failed: it keeps INVALID/WRITE through resyncs and
  readbacks that differ from it (a resync and its first readback can land
  between a refused put and the put's answer to the client, which must see
  the put fail: only readbacks published after that answer are compared,
  and the PLC is asked for a fresh one then), and one
  whose last write's outcome is unknown keeps INVALID/TIMEOUT until its
  read back decides.

The alarms themselves are `Health`'s (setpoint problems); this decides which.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Iterable
from typing import Any, Final

import numpy as np
from fastcs.attributes import AttrR

from fastcs_ethercat.ioc.alarms import Status
from fastcs_ethercat.ioc.fastcs_adapter import records_of
from fastcs_ethercat.ioc.health import Health

logger = logging.getLogger(__name__)

WAITING: Final = "waiting for the value the PLC holds"

Reread = Callable[[], None]
"""Asks the poller to report what the PLC holds on its next cycle, changed
or not (the write path's `Poller.invalidate` of the output's group)."""


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
        self._refusals: dict[int, object] = {}
        """Attribute -> the failed write it shows now (a token per failure):
        a later decision drops it, so a readback of an older one is ignored."""

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
        self._decided(attribute)
        await self._show(attribute, value)

    async def failed(
        self,
        attribute: AttrR[Any, Any],
        value: Any,
        why: str,
        reread: Reread | None = None,
    ) -> None:
        """`value` did not reach the PLC: INVALID/WRITE until a later write
        succeeds, or a readback shows the PLC holds `value` all the same
        (it held it already, or another client wrote it). Readbacks count
        from once the put's answer has gone out, when `reread` asks the PLC
        for a fresh one (its value may not change again)."""
        self._decided(attribute)
        refusal = self._refusals[id(attribute)] = object()
        await self._show(attribute, value, Status.WRITE, why)
        # after `show_setpoint_soon`'s call: the client has seen the failure
        asyncio.get_running_loop().call_soon(
            self._compare_readbacks, attribute, value, refusal, reread
        )

    async def unknown(self, attribute: AttrR[Any, Any], value: Any, why: str) -> None:
        """A write of `value` whose outcome is unknown (not answered, nor a
        read back): INVALID/TIMEOUT until the write path has read it back
        once the target answers again (then `written` or `failed`)."""
        self._decided(attribute)
        await self._show(attribute, value, Status.TIMEOUT, why)

    def _decided(self, attribute: AttrR[Any, Any]) -> None:
        """A new verdict on this setpoint: what watched the last one stops."""
        self.health.unwatch_value(attribute)
        self._refusals.pop(id(attribute), None)

    def _compare_readbacks(
        self,
        attribute: AttrR[Any, Any],
        value: Any,
        refusal: object,
        reread: Reread | None,
    ) -> None:
        """From now on, each readback of this output is compared with the
        failed write's `value` (unless a later verdict came first)."""
        if self._refusals.get(id(attribute)) is not refusal:
            return

        async def compare(attribute: AttrR[Any, Any], readback: Any) -> None:
            if self._refusals.get(id(attribute)) is not refusal:
                return
            if _same(readback, value):  # the PLC holds it: the setpoint is true
                self._decided(attribute)
                await self._show(attribute, readback)
            else:
                self.health.watch_value(attribute, compare)  # the next one

        self.health.watch_value(attribute, compare)
        if reread is not None:
            reread()

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


def _same(readback: Any, value: Any) -> bool:
    """A readback equal to a written value (arrays element by element)."""
    if isinstance(readback, np.ndarray) or isinstance(value, np.ndarray):
        return bool(np.array_equal(readback, value))
    return bool(readback == value)
