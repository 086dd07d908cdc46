"""Attributes that show a value made from another's (a scaled point's
engineering value from its raw count): one read gives both, so each value
of the leader is converted for its followers, theirs too, in one place."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from fastcs.attributes import Attribute, AttrR

from fastcs_ethercat.ioc.publish import Failure

Convert = Callable[[Any], Any]
"""A leader's value -> its follower's value."""
Led = list[tuple[AttrR[Any, Any], Convert]]


class Followers:
    """Who follows whom, and the values they get."""

    def __init__(self) -> None:
        self._led: dict[int, Led] = {}

    def __bool__(self) -> bool:
        return bool(self._led)

    def add(
        self, leader: Attribute[Any, Any], follower: AttrR[Any, Any], convert: Convert
    ) -> None:
        """`follower` gets `convert(value)` of every value of `leader`."""
        self._led.setdefault(id(leader), []).append((follower, convert))

    def of(self, leader: Attribute[Any, Any]) -> Led:
        """`leader`'s own followers, each with its conversion."""
        return self._led.get(id(leader), [])

    def with_followers(
        self, attributes: Iterable[Attribute[Any, Any]]
    ) -> Iterator[Attribute[Any, Any]]:
        """Each of `attributes`, then its own followers."""
        led = self._led
        for attribute in attributes:
            yield attribute
            for follower, _ in led.get(id(attribute), ()):
                yield follower

    def expand(
        self, values: list[tuple[AttrR[Any, Any], Any]], failures: list[Failure]
    ) -> list[tuple[AttrR[Any, Any], Any]]:
        """`values`, each followed by its followers' values (theirs too); a
        conversion that raises is a failure of that follower alone."""
        expanded: list[tuple[AttrR[Any, Any], Any]] = []
        for attribute, value in values:
            expanded.append((attribute, value))
            led = self._led.get(id(attribute))
            if led is not None:
                self._add(led, value, expanded, failures)
        return expanded

    def _add(
        self,
        led: Led,
        value: Any,
        expanded: list[tuple[AttrR[Any, Any], Any]],
        failures: list[Failure],
    ) -> None:
        for follower, convert in led:
            try:
                converted = convert(value)
            except Exception as error:  # one value must not stop the others
                failures.append((follower, error))
                continue
            expanded.append((follower, converted))
            theirs = self._led.get(id(follower))
            if theirs is not None:
                self._add(theirs, converted, expanded, failures)
