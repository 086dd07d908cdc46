"""`collector.held`, `hold` and `release`: no collection within, the
collector's state restored, what was built meanwhile in the oldest
generation."""

from __future__ import annotations

import gc
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


def test_what_a_burst_built_goes_to_the_oldest_generation() -> None:
    with held():
        built = Built()
    assert gc.get_count()[0] < 10  # no young collection waits for it
    assert any(thing is built for thing in gc.get_objects(generation=2))


def test_held_leaves_frozen_objects_frozen() -> None:
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        with held():
            Built()
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()


def test_hold_stops_collection_until_release_and_ages_what_was_built() -> None:
    hold()
    try:
        assert not gc.isenabled()
        built = Built()
    finally:
        release()
    assert gc.isenabled()
    assert gc.get_count()[0] < 10
    assert any(thing is built for thing in gc.get_objects(generation=2))


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
