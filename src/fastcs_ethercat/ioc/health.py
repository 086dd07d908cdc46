"""Which attributes are in alarm, and why: the one place the IOC raises alarms.

An attribute can be invalid for several reasons at once (the target is gone,
its terminal left OP, its sum-read item failed); it is back to the alarm of
its own value (`alarms.value_alarm`: NO_ALARM, or a set Error bit's MAJOR)
only when every reason is gone. EPICS alarms set through `ioc.alarms` are
not sticky: the next value published carries its own alarm. So while an
attribute is in alarm its new values are held back (the last one is kept)
and published when the last reason goes, followed by its value's alarm.

Reasons that a fresh value disproves (`FRESH`: the read failed, the target
was unreachable) go by themselves when the poller hands on a new value;
the others (a terminal's state, a chain change) only by `mark_ok`.

An attribute may have followers (`follow`, kept by `ioc.followers`):
attributes that show a value made from each of its values (a scaled value's
raw count and engineering value come from one read) and share its every
alarm.

An output's setpoint PVs can also have a problem of their own, which its
readback does not share: a write that did not reach the PLC, one whose
outcome is unknown, a setpoint waiting for what the PLC holds
(`ioc.setpoints` decides which). It is shown on the setpoint PVs over any
other reason until `setpoint_fine`; the readback PVs keep showing the PLC.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass
from typing import Any, Final

from fastcs.attributes import Attribute, AttrR

from fastcs_ethercat.ioc import alarms
from fastcs_ethercat.ioc.alarms import NO_ALARM, AlarmState, Severity, Status
from fastcs_ethercat.ioc.fastcs_adapter import Parts
from fastcs_ethercat.ioc.followers import Convert, Followers
from fastcs_ethercat.ioc.publish import Failure, Published, Publisher

logger = logging.getLogger(__name__)

COMM: Final = "comm"
"""The target does not answer (or its runtime is stopped)."""
READ: Final = "read"
"""The point's sum-read item failed."""
FRESH: Final = frozenset({COMM, READ})
"""Reasons a freshly read value proves wrong."""


@dataclass(frozen=True)
class Reason:
    """Why one attribute is invalid: an alarm status and a text."""

    status: Status
    message: str

    def alarm(self) -> AlarmState:
        return AlarmState(Severity.INVALID, self.status, self.message)


ValueWatch = Callable[[AttrR[Any, Any], Any], Awaitable[None]]
"""Called with an attribute and the value just published for it."""


class Health:
    """Alarm reasons per attribute, and the values held back meanwhile."""

    def __init__(self, publisher: Publisher | None = None) -> None:
        self.publisher = publisher or Publisher()
        self._reasons: dict[int, dict[str, Reason]] = {}
        self._attributes: dict[int, Attribute[Any, Any]] = {}
        self._held: dict[int, Any] = {}
        self.followers = Followers()
        self._setpoint: dict[int, Reason] = {}
        """Problems of setpoint PVs alone (ioc.setpoints)."""
        self._watches: dict[int, ValueWatch] = {}
        self.published = 0
        """Alarm changes published (for tests and statistics)."""
        self.failures = 0
        """Alarm publications that raised (logged, never propagated)."""

    def follow(
        self, leader: Attribute[Any, Any], follower: AttrR[Any, Any], convert: Convert
    ) -> None:
        """`follower` gets `convert(value)` of every value posted for
        `leader`, at its time, and every alarm reason `leader` gets."""
        self.followers.add(leader, follower, convert)

    def is_invalid(self, attribute: Attribute[Any, Any]) -> bool:
        return bool(self._reasons.get(id(attribute)))

    def reasons(self, attribute: Attribute[Any, Any]) -> list[str]:
        return sorted(self._reasons.get(id(attribute), {}))

    @property
    def invalid_count(self) -> int:
        return sum(1 for reasons in self._reasons.values() if reasons)

    def mark_invalid(
        self,
        attributes: Iterable[Attribute[Any, Any]],
        reason: str,
        status: Status = Status.COMM,
        message: str = "",
    ) -> None:
        """Put `attributes` into INVALID alarm for `reason` (idempotent)."""
        entry = Reason(status, message)
        for attribute in self.followers.with_followers(attributes):
            key = id(attribute)
            reasons = self._reasons.setdefault(key, {})
            self._attributes[key] = attribute
            if reasons.get(reason) == entry:
                continue
            reasons[reason] = entry
            self._publish(attribute, entry)

    async def mark_ok(
        self, attributes: Iterable[Attribute[Any, Any]], reason: str
    ) -> None:
        """Drop `reason`; an attribute with no reason left is valid again."""
        for attribute in list(self.followers.with_followers(attributes)):
            await self._drop(attribute, {reason})

    async def post(self, attribute: AttrR[Any, Any], value: Any) -> None:
        """A fresh value: publish it, unless the attribute
        stays in alarm; then its followers' values."""
        key = id(attribute)
        if key in self._reasons:
            await self._hold(attribute, value)
        else:
            await self.publisher.publish(attribute, value)
            if self._watches:
                await self._watched(attribute, value)
        for follower, convert in self.followers.of(attribute):
            await self.post(follower, convert(value))

    async def post_batch(self, values: list[tuple[AttrR[Any, Any], Any]]) -> Published:
        """Fresh values of one poll cycle, as `post` for each
        (followers included); the ones not in alarm published together."""
        failures: list[Failure] = []
        if self.followers:
            values = self.followers.expand(values, failures)
        reasons = self._reasons
        if reasons:
            held = [(a, v) for a, v in values if id(a) in reasons]
            values = [(a, v) for a, v in values if id(a) not in reasons]
            for attribute, value in held:
                try:
                    await self._hold(attribute, value)
                except Exception as error:  # one value must not stop the others
                    failures.append((attribute, error))
        published = await self.publisher.publish_batch(values)
        if self._watches:  # as `post` does, for the values published together
            failed = {id(attribute) for attribute, _ in published.failures}
            for attribute, value in values:
                if id(attribute) in self._watches and id(attribute) not in failed:
                    await self._watched(attribute, value)
        return published._replace(failures=failures + published.failures)

    async def _hold(self, attribute: AttrR[Any, Any], value: Any) -> None:
        """A fresh value of an attribute in alarm: kept, shown when the
        alarm ends; the fresh value disproves `FRESH` reasons."""
        self._held[id(attribute)] = value
        await self._drop(attribute, FRESH)

    def watch_value(self, attribute: AttrR[Any, Any], watch: ValueWatch) -> None:
        """Call `watch` once, with the next value published for `attribute`
        (a fresh one, or the one held while it was in alarm)."""
        self._watches[id(attribute)] = watch

    def unwatch_value(self, attribute: AttrR[Any, Any]) -> None:
        self._watches.pop(id(attribute), None)

    async def _watched(self, attribute: AttrR[Any, Any], value: Any) -> None:
        watch = self._watches.pop(id(attribute), None)
        if watch is not None:
            await watch(attribute, value)

    # -- setpoints -----------------------------------------------------------------

    def setpoint_problem(
        self, attribute: Attribute[Any, Any], status: Status, message: str
    ) -> None:
        """The setpoint PVs alone are INVALID with `status` (over any other
        reason) until `setpoint_fine`; shown by `show_setpoint(_soon)`."""
        self._setpoint[id(attribute)] = Reason(status, message)

    def setpoint_status(self, attribute: Attribute[Any, Any]) -> Status | None:
        """The status of the setpoint's own problem, None without one."""
        own = self._setpoint.get(id(attribute))
        return None if own is None else own.status

    def setpoint_fine(self, attribute: Attribute[Any, Any]) -> None:
        """The setpoint's own problem is gone: its PVs show the attribute's
        other reasons, if any (once shown)."""
        self._setpoint.pop(id(attribute), None)

    def setpoint_alarm(self, attribute: Attribute[Any, Any]) -> AlarmState:
        """What the setpoint PVs show now."""
        own = self._setpoint.get(id(attribute))
        if own is not None:
            return own.alarm()
        reasons = self._reasons.get(id(attribute))
        return next(iter(reasons.values())).alarm() if reasons else NO_ALARM

    def show_setpoint(self, attribute: Attribute[Any, Any]) -> None:
        """Publish `setpoint_alarm` on the setpoint PVs."""
        self._publish_state(attribute, self.setpoint_alarm(attribute), Parts.SETPOINT)

    def show_setpoint_soon(self, attribute: Attribute[Any, Any]) -> None:
        """`show_setpoint` once the put under way has been handled: FastCS's
        put handler stages its own verdict on the record (MAJOR/WRITE or no
        alarm) after the write path returns, then asks EPICS to complete
        the put. The setpoint record is held locked from now until ours is
        raised after FastCS's, so the completion (an EPICS callback thread
        locks the record to process it) always shows the IOC's verdict: the
        client of `caput -c` sees INVALID/WRITE or INVALID/TIMEOUT, not
        FastCS's MAJOR."""
        release = alarms.hold_setpoint(attribute)

        def show() -> None:
            try:
                self.show_setpoint(attribute)
            finally:
                release()

        asyncio.get_running_loop().call_soon(show)

    async def _drop(self, attribute: Attribute[Any, Any], gone: Iterable[str]) -> None:
        key = id(attribute)
        reasons = self._reasons.get(key)
        if reasons is None:
            return
        removed = [reason for reason in gone if reasons.pop(reason, None)]
        if not removed:
            return
        if reasons:
            remaining = next(iter(reasons.values()))
            self._publish(attribute, remaining)  # the reason shown may change
            return
        del self._reasons[key]
        self._attributes.pop(key, None)
        holding = key in self._held
        held = self._held.pop(key, None)
        published = False
        if holding and isinstance(attribute, AttrR):
            try:
                await self.publisher.publish(attribute, held)
                published = True
            except Exception as error:  # one line: a flood of these is unreadable
                logger.warning(
                    "cannot post the held value of %s: %s", _name(attribute), error
                )
        self._clear(attribute)
        if published and isinstance(attribute, AttrR):
            await self._watched(attribute, held)

    def _parts(self, attribute: Attribute[Any, Any]) -> Parts:
        """A setpoint with its own problem keeps showing it."""
        return Parts.READBACK if id(attribute) in self._setpoint else Parts.ALL

    def _publish(self, attribute: Attribute[Any, Any], reason: Reason) -> None:
        self._publish_state(attribute, reason.alarm(), self._parts(attribute))

    def _clear(self, attribute: Attribute[Any, Any]) -> None:
        # a set Error bit stays MAJOR, and the values of its channel with it
        if isinstance(attribute, AttrR):
            state = self.publisher.value_alarm(attribute)
        else:
            state = alarms.value_alarm(attribute)
        self._publish_state(attribute, state, self._parts(attribute))

    def _publish_state(
        self, attribute: Attribute[Any, Any], state: AlarmState, parts: Parts
    ) -> None:
        try:
            alarms.publish_alarm(attribute, state, parts)
            self.published += 1
        except Exception as error:  # an alarm must never stop polling
            self.failures += 1
            logger.warning("cannot set the alarm of %s: %s", _name(attribute), error)


def _name(attribute: Attribute[Any, Any]) -> str:
    """`PREFIX.ETH1.RIO1.MOD5.Name`: short, unlike an attribute's repr."""
    return attribute.full_name or repr(attribute)
