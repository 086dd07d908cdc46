"""Which attributes are in alarm, and why: the one place the IOC raises alarms.

An attribute can be invalid for several reasons at once (the target is gone,
its terminal left OP, its sum-read item failed); it is back to NO_ALARM only
when every reason is gone. EPICS alarms set through `ioc.alarms` are not
sticky: the next value FastCS publishes carries NO_ALARM. So while an
attribute is in alarm its new values are held back (the last one is kept)
and published when the last reason goes, followed by `clear_alarm`.

Reasons that a fresh value disproves (`FRESH`: the read failed, the target
was unreachable) go by themselves when the poller hands on a new value;
the others (a terminal's state, a chain change) only by `mark_ok`.

An attribute may have followers (`follow`): attributes that show a value
made from each of its values (a scaled value's raw count and engineering
value come from one read) and share its every alarm.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Final

from fastcs.attributes import Attribute, AttrR

from fastcs_ethercat.ioc import alarms
from fastcs_ethercat.ioc.alarms import Severity, Status
from fastcs_ethercat.ioc.publish import Publisher

logger = logging.getLogger(__name__)

COMM: Final = "comm"
"""The target does not answer (or its runtime is stopped)."""
READ: Final = "read"
"""The point's sum-read item failed."""
FRESH: Final = frozenset({COMM, READ})
"""Reasons a freshly read value proves wrong."""


Convert = Callable[[Any], Any]
"""A leader's value -> its follower's value."""


@dataclass(frozen=True)
class Reason:
    """Why one attribute is invalid: an alarm status and a text."""

    status: Status
    message: str


class Health:
    """Alarm reasons per attribute, and the values held back meanwhile."""

    def __init__(self, publisher: Publisher | None = None) -> None:
        self.publisher = publisher or Publisher()
        self._reasons: dict[int, dict[str, Reason]] = {}
        self._attributes: dict[int, Attribute[Any, Any]] = {}
        self._held: dict[int, tuple[Any, float | None]] = {}
        self._followers: dict[int, list[tuple[AttrR[Any, Any], Convert]]] = {}
        self.published = 0
        """Alarm changes published (for tests and statistics)."""
        self.failures = 0
        """Alarm publications that raised (logged, never propagated)."""

    def follow(
        self, leader: Attribute[Any, Any], follower: AttrR[Any, Any], convert: Convert
    ) -> None:
        """`follower` gets `convert(value)` of every value posted for
        `leader`, at its time, and every alarm reason `leader` gets."""
        self._followers.setdefault(id(leader), []).append((follower, convert))

    def _with_followers(
        self, attributes: Iterable[Attribute[Any, Any]]
    ) -> Iterator[Attribute[Any, Any]]:
        followers = self._followers
        for attribute in attributes:
            yield attribute
            for follower, _ in followers.get(id(attribute), ()):
                yield follower

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
        for attribute in self._with_followers(attributes):
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
        for attribute in list(self._with_followers(attributes)):
            await self._drop(attribute, {reason})

    async def post(
        self, attribute: AttrR[Any, Any], value: Any, stamp: float | None = None
    ) -> None:
        """A fresh value read at `stamp`: publish it, unless the attribute
        stays in alarm; then its followers' values."""
        key = id(attribute)
        if key in self._reasons:
            self._held[key] = (value, stamp)
            await self._drop(attribute, FRESH)
        else:
            await self.publisher.publish(attribute, value, stamp)
        followers = self._followers.get(key)
        if followers is not None:
            for follower, convert in followers:
                await self.post(follower, convert(value), stamp)

    def write_failed(self, attribute: Attribute[Any, Any], message: str) -> None:
        """A write the target refused: alarm once FastCS has failed the put
        (it raises the record to MAJOR itself, which would hide INVALID);
        the next value clears it."""
        reason = Reason(Status.WRITE, message)
        for written in self._with_followers([attribute]):
            if not self.is_invalid(written):
                asyncio.get_running_loop().call_soon(self._publish, written, reason)

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
        held = self._held.pop(key, None)
        if held is not None and isinstance(attribute, AttrR):
            try:
                await self.publisher.publish(attribute, *held)
            except Exception as error:  # one line: a flood of these is unreadable
                logger.warning(
                    "cannot post the held value of %s: %s", _name(attribute), error
                )
        self._clear(attribute)

    def _publish(self, attribute: Attribute[Any, Any], reason: Reason) -> None:
        try:
            alarms.set_alarm(attribute, Severity.INVALID, reason.status, reason.message)
            self.published += 1
        except Exception as error:  # an alarm must never stop polling
            self.failures += 1
            logger.warning("cannot set the alarm of %s: %s", _name(attribute), error)

    def _clear(self, attribute: Attribute[Any, Any]) -> None:
        try:
            alarms.clear_alarm(attribute)
            self.published += 1
        except Exception as error:
            self.failures += 1
            logger.warning("cannot clear the alarm of %s: %s", _name(attribute), error)


def _name(attribute: Attribute[Any, Any]) -> str:
    """`PREFIX.ETH1.RIO1.MOD5.Name`: short, unlike an attribute's repr."""
    return attribute.full_name or repr(attribute)
