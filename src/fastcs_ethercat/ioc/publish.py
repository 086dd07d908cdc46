"""Post values to their PVs, a poll cycle's changed values together.

The one path of every value the IOC serves: a poll cycle's changed values,
and the IOC's own (diagnostics, statistics, CoE reads). Each value is put
into its record (`fastcs_adapter.ValueRoute`), which EPICS processes at
once: its alarm limits, deadbands and links, the monitors of CA and PVA
clients, its time the time of that processing (a few milliseconds after
the read). Only values that changed are posted.

Alarms are not sticky here either: a published value carries its own alarm,
the one record support gives it (its limits, a bi's OSV, UDF for NaN),
raised by its datatype's table where its record has no such field (a bit
field's `AlarmInt`) and by its channel's status bits when they are in alarm
(`ioc.channel_alarms`); see `ioc.alarms`, `ioc.health`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Final, NamedTuple

from fastcs.attributes import AttrR

from fastcs_ethercat.collector import freeze_new, settle_garbage_collector
from fastcs_ethercat.ioc import alarms
from fastcs_ethercat.ioc.alarms import AlarmState, Severity, state_alarm
from fastcs_ethercat.ioc.channel_alarms import ChannelAlarms
from fastcs_ethercat.ioc.datatypes import AlarmInt, severity_table
from fastcs_ethercat.ioc.deadband import Deadbands
from fastcs_ethercat.ioc.fastcs_adapter import ValueRoute

FREEZE_AFTER_ROUTES: Final = 100
"""A batch that made this many routes (a first cycle) freezes the heap again."""

Failure = tuple[AttrR[Any, Any], Exception]
"""An attribute whose value could not be posted, and why."""


class Published(NamedTuple):
    """What one batch did: values posted, and the ones that failed."""

    posted: int
    failures: list[Failure]


class _Route:
    """What posting one attribute's values needs, looked up once (FastCS's
    `datatype` is a property): its record's route, its datatype's validate
    and equal, its deadband (0: none), the severity table the IOC raises for
    its value (None: its record gives it, or it has none) and the channel
    severity it was last posted with."""

    __slots__ = (
        "band", "carried", "carriers", "channel", "equal", "route", "severity_of",
        "validate",
    )  # fmt: skip

    def __init__(
        self, attribute: AttrR[Any, Any], band: float, channels: ChannelAlarms
    ) -> None:
        datatype = attribute.datatype
        self.channel = channels.channel_of(attribute)
        """The channel whose status bits this value carries (None: none)."""
        self.carriers = channels.values_of(attribute)
        """The values that carry this status bit (none if it is none)."""
        self.route = ValueRoute(attribute)
        self.validate = datatype.validate
        self.equal = datatype.equal
        self.band = band
        self.severity_of = (
            severity_table(datatype) if isinstance(datatype, AlarmInt) else None
        )
        self.carried = 0


class _Batch:
    """What one batch has done so far."""

    def __init__(self) -> None:
        self.posted = 0
        self.made = 0
        """Routes made (not prepared ahead)."""
        self.failures: list[Failure] = []


class Publisher:
    """Publishes values of attributes the IOC keeps, once the transports serve.

    Until `start()` (the transports' PVs exist only from when they serve),
    values go through `update()`. The first value published for an attribute
    is posted even when it equals the attribute's value, so its records are
    processed once they serve (their alarm and time set). A number with a deadband
    (`ioc.deadband`) is posted only when it moved further than that from the
    value posted last, which its attribute keeps.
    """

    def __init__(self, deadbands: Deadbands | None = None) -> None:
        self.started = False
        self.deadbands = deadbands or Deadbands()
        self.posted = 0
        """Values posted since start (a running total, for rates)."""
        self.within_deadband = 0
        """New values not posted: within their deadband of the last posted."""
        self._routes: dict[int, _Route] = {}
        self.channels = ChannelAlarms()
        """Which values carry their channel's status bits' alarm."""
        self._prepared: dict[int, _Route] = {}
        """Routes made ahead (`prepare`), taken at each attribute's first value."""
        self._first: set[int] = set()
        """Attributes posted even if equal (their current value at `start`)."""

    def prepare(self, attributes: Iterable[AttrR[Any, Any]]) -> None:
        """Make the routes of `attributes` now (once their PVs exist, before
        they serve), not at their first values: a first poll cycle of a rack
        would otherwise make thousands while clients connect."""
        freeze_new()  # the tree and its PVs, out of the collector's walks
        prepared = self._prepared
        for attribute in attributes:
            if id(attribute) not in self._routes:
                prepared[id(attribute)] = self._route(attribute)
        freeze_new()  # routes live as long as the IOC

    async def start(self, own: Iterable[AttrR[Any, Any]] = ()) -> None:
        """The database serves: post straight to its records from now on,
        first the current values of `own` (attributes whose value the IOC
        set before, not read from the target)."""
        self.started = True
        initial = [(a, a.get()) for a in own if a.get() is not None]
        self._first.update(id(attribute) for attribute, _ in initial)
        await self.publish_batch(initial)
        settle_garbage_collector()

    async def publish(self, attribute: AttrR[Any, Any], value: Any) -> bool:
        """Post `value` (if new); True if posted."""
        posted, failures = await self.publish_batch([(attribute, value)])
        if failures:
            raise failures[0][1]
        return posted == 1

    async def publish_batch(
        self,
        values: Iterable[tuple[AttrR[Any, Any], Any]],
    ) -> Published:
        """Post each new value; a value that fails
        does not stop the others. A channel's values go after its status
        bits, with the worst of their severities (`ioc.channel_alarms`); a
        value whose channel's alarm changed is posted again, unchanged."""
        if not self.started:
            return await self._update_each(values)
        batch = _Batch()
        carrying: list[tuple[_Route, AttrR[Any, Any], Any]] = []
        touched: dict[int, AttrR[Any, Any]] = {}
        routes = self._routes
        for attribute, value in values:
            entry = routes.get(id(attribute))
            if entry is None:
                entry = self._first_route(batch, attribute)
            if entry.channel is not None:
                carrying.append((entry, attribute, value))
            elif self._post(batch, entry, attribute, value, None):
                for carrier in entry.carriers:
                    touched[id(carrier)] = carrier
        for _, attribute, _ in carrying:
            touched.pop(id(attribute), None)
        for attribute in touched.values():  # its value as it was, its alarm not
            entry = routes.get(id(attribute))
            if entry is not None and entry.channel is not None:
                carrying.append((entry, attribute, attribute.get()))
        worst: dict[int, int] = {}  # a channel's severity, once per batch
        for entry, attribute, value in carrying:
            channel: Any = entry.channel
            severity = worst.get(id(channel))
            if severity is None:
                severity = worst[id(channel)] = channel.severity()
            self._post(batch, entry, attribute, value, severity)
        if batch.made >= FREEZE_AFTER_ROUTES:
            freeze_new()  # routes live as long as the IOC
        self.posted += batch.posted
        return Published(batch.posted, batch.failures)

    def value_alarm(self, attribute: AttrR[Any, Any]) -> AlarmState:
        """The alarm of the attribute's value by itself and its channel's
        status bits (what it shows once no other alarm holds it)."""
        own = alarms.value_alarm(attribute)
        if not self.channels.carries(attribute):
            return own
        carried = self.channels.severity(attribute)
        route = self._routes.get(id(attribute))
        if route is not None:
            route.carried = carried
        if carried > own.severity:
            return AlarmState(Severity(carried), alarms.VALUE_STATUS)
        return own

    def _first_route(self, batch: _Batch, attribute: AttrR[Any, Any]) -> _Route:
        """The attribute's route at its first value: prepared, or made now;
        its first value is posted even if equal (`_first`)."""
        entry = self._prepared.pop(id(attribute), None)
        if entry is None:
            entry = self._route(attribute)
            batch.made += 1
        self._routes[id(attribute)] = entry
        self._first.add(id(attribute))
        return entry

    def _post(
        self,
        batch: _Batch,
        entry: _Route,
        attribute: AttrR[Any, Any],
        value: Any,
        carried: int | None,
    ) -> bool:
        """Post `value` if new (or its channel's alarm, `carried`, is);
        whether it was posted."""
        try:
            validated = entry.validate(value)
            if self._first and id(attribute) in self._first:  # posted even if equal
                self._first.discard(id(attribute))
            else:
                unchanged_alarm = carried is None or carried == entry.carried
                band = entry.band
                if band:
                    if abs(validated - attribute.get()) <= band and unchanged_alarm:
                        self.within_deadband += 1
                        return False
                elif unchanged_alarm and entry.equal(attribute.get(), validated):
                    return False
            severity_of = entry.severity_of
            severity = severity_of(validated) if severity_of is not None else 0
            if carried is not None:
                entry.carried = carried
                if carried > severity:
                    severity = carried
            if severity:  # a state, its own or its channel's: its alarm goes with it
                entry.route.post_alarmed(validated, *state_alarm(severity))
            else:
                entry.route.post_value(validated)
        except Exception as error:
            batch.failures.append((attribute, error))
            return False
        batch.posted += 1
        return True

    def _route(self, attribute: AttrR[Any, Any]) -> _Route:
        return _Route(attribute, self.deadbands.of_attribute(attribute), self.channels)

    async def _update_each(
        self, values: Iterable[tuple[AttrR[Any, Any], Any]]
    ) -> Published:
        """Before the transports serve: FastCS's own `update()`."""
        failures: list[Failure] = []
        posted = 0
        for attribute, value in values:
            try:
                validated = attribute.datatype.validate(value)
                if attribute.datatype.equal(attribute.get(), validated):
                    continue
                await attribute.update(validated)
                posted += 1
            except Exception as error:
                failures.append((attribute, error))
        return Published(posted, failures)
