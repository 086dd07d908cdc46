"""`collector.held`: no collection within, the collector's state restored."""

from __future__ import annotations

import gc

import pytest

from fastcs_ethercat.collector import held


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
