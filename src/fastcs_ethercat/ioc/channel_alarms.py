"""A value carries its channel's alarm.

A terminal channel serves its value beside the status bits the terminal
reads with it (`CH1:Value`, `CH1:Error`, `CH1:Overrange`...). Each status bit
carries its own severity (Error MAJOR, over/underrange and limits MINOR: the
datatype tables, `ioc.datatypes`); the channel's values carry the worst of
them too, status STATE, so a synoptic that shows only the value shows that
the channel is in error. Record support adds the value's own limits (HIHI
and the rest) on top; the link and the terminal's state reach every PV
through `ioc.health`.

A channel is one controller: its status bits are the attributes whose
datatype has a severity table, its values the plain numbers read from the
target beside them.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from fastcs.attributes import AttrR, AttrW
from fastcs.datatypes import Float, Int

from fastcs_ethercat.ioc.datatypes import severity_table


class Channel:
    """The status bits of one channel, each with its datatype's table."""

    __slots__ = ("statuses",)

    def __init__(self, statuses: tuple[AttrR[Any, Any], ...]) -> None:
        self.statuses = tuple((s, severity_table(s.datatype)) for s in statuses)

    def severity(self) -> int:
        """The worst severity of the status bits now."""
        worst = 0
        for status, severity_of in self.statuses:
            severity = severity_of(status.get())
            if severity > worst:
                worst = severity
        return worst


class ChannelAlarms:
    """Which values carry which status bits' severity."""

    def __init__(self) -> None:
        self._channels: dict[int, Channel] = {}
        """A value's id -> its channel."""
        self._values: dict[int, tuple[AttrR[Any, Any], ...]] = {}
        """A status bit's id -> the values of its channel."""

    def add(self, attributes: Iterable[AttrR[Any, Any]]) -> None:
        """Group `attributes` (read from the target) by their controller."""
        by_controller: dict[tuple[str, ...], list[AttrR[Any, Any]]] = {}
        for attribute in attributes:
            by_controller.setdefault(tuple(attribute.path), []).append(attribute)
        for members in by_controller.values():
            statuses = tuple(a for a in members if severity_table(a.datatype))
            values = tuple(a for a in members if _carries(a))
            if statuses and values:
                channel = Channel(statuses)
                for value in values:
                    self._channels[id(value)] = channel
                for status in statuses:
                    self._values[id(status)] = values

    def channel_of(self, value: AttrR[Any, Any]) -> Channel | None:
        """The channel whose status bits `value` carries, None if none."""
        return self._channels.get(id(value))

    def carries(self, attribute: AttrR[Any, Any]) -> bool:
        """Whether `attribute` is a value with status bits beside it."""
        return id(attribute) in self._channels

    def values_of(self, status: AttrR[Any, Any]) -> tuple[AttrR[Any, Any], ...]:
        """The values that carry `status` (none if it is no status bit)."""
        return self._values.get(id(status), ())

    def severity(self, value: AttrR[Any, Any]) -> int:
        """The worst severity of the status bits beside `value` now."""
        channel = self._channels.get(id(value))
        return 0 if channel is None else channel.severity()


def _carries(attribute: AttrR[Any, Any]) -> bool:
    """A plain number read from the target (not an output's readback)."""
    return (
        isinstance(attribute.datatype, Float | Int)
        and not isinstance(attribute, AttrW)
        and severity_table(attribute.datatype) is None
    )
