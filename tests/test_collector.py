"""`collector.held`, `hold` and `release`: no collection within, the
collector's state restored, what was built meanwhile in the oldest
generation."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from pathlib import Path

import pytest

from fastcs_ethercat.collector import held, hold, release


def test_held_stops_collection_within_and_restores_it() -> None:
    assert gc.isenabled()
    with held():
        assert not gc.isenabled()
    assert gc.isenabled()


def test_held_restores_the_collector_after_an_error() -> None:
    with pytest.raises(ValueError), held():
        raise ValueError("broken document")
    assert gc.isenabled()


def test_held_leaves_a_disabled_collector_disabled() -> None:
    gc.disable()
    try:
        with held():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()


class Built:
    """A tracked object, as a parse builds them."""


@pytest.fixture
def nothing_frozen() -> Iterator[None]:
    """The promise to age what was built holds while nothing is frozen: code
    run earlier in this process (an IOC's start) may have frozen its objects;
    they are thawed for the test and frozen again after it."""
    frozen = gc.get_freeze_count()
    if frozen:
        gc.unfreeze()
    yield
    if frozen:
        gc.freeze()


def in_generation(thing: object, generation: int) -> bool:
    return any(other is thing for other in gc.get_objects(generation=generation))


def aged(thing: object) -> bool:
    """In the oldest generation: no young collection waits for it (whatever
    other threads allocate meanwhile)."""
    return in_generation(thing, 2) and not in_generation(thing, 0)


@pytest.mark.usefixtures("nothing_frozen")
def test_what_a_burst_built_goes_to_the_oldest_generation() -> None:
    with held():
        built = Built()
    assert aged(built)


def tracked(thing: object) -> bool:
    """In one of the collector's generations: frozen objects are in none."""
    return any(in_generation(thing, generation) for generation in range(3))


def test_held_leaves_frozen_objects_frozen() -> None:
    """Asked of one frozen object, not of the freeze count: a frozen object
    that dies meanwhile (another thread's) lowers the count."""
    before = Built()
    gc.freeze()
    try:
        with held():
            Built()
        assert not tracked(before)
    finally:
        gc.unfreeze()


@pytest.mark.usefixtures("nothing_frozen")
def test_hold_stops_collection_until_release_and_ages_what_was_built() -> None:
    hold()
    try:
        assert not gc.isenabled()
        built = Built()
    finally:
        release()
    assert gc.isenabled()
    assert aged(built)


def test_nothing_is_aged_while_something_is_frozen() -> None:
    """Ageing thaws what is frozen (`gc.unfreeze`), so it waits."""
    gc.freeze()
    try:
        with held():
            built = Built()
        assert not in_generation(built, 2)
    finally:
        gc.unfreeze()


def test_release_without_hold_changes_nothing() -> None:
    gc.disable()
    try:
        release()
        assert not gc.isenabled()
    finally:
        gc.enable()
    release()
    assert gc.isenabled()


def test_hold_leaves_a_disabled_collector_to_its_owner() -> None:
    gc.disable()
    try:
        hold()
        release()
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_a_full_parse_makes_no_cyclic_garbage() -> None:
    """What `held` promotes would wait for a full collection."""
    from fastcs_ethercat.esi import parse_all

    source = Path(__file__).parent / "data" / "esi"
    gc.collect()
    gc.disable()
    try:
        result = parse_all(source)
        assert result.devices
        assert gc.collect() == 0
    finally:
        gc.enable()
