"""The garbage collector, kept out of the way of bursts that only build.

Parsing an ESI document builds some 100 000 objects that all live on: the
collector's passes over them were 10 % of a full parse. An IOC builds
hundreds of thousands of objects that live as long as it does (the controller
tree, its records and PVs). With CPython's default threshold (a young
collection every 700 objects) the collector walks them again and again while
they are built: 565 collections, 0.36 s of the start of 104 terminals. And a
rack whose every value changes allocates short-lived tuples at 100 000 values
a second: collected 150 times a second, half its CPU. And a command's start
imports some 600 modules whose objects all live on: the collector walked
them ~80 times (one middle-generation pass 25 ms) before the IOC first
talked to its target.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Final

GC_THRESHOLD: Final = 50_000
"""Tracked objects allocated (net) before a young collection; by then a poll
cycle's short-lived tuples are gone."""


_holding = False
"""`hold` turned the collector off and `release` has not turned it on yet."""


def _to_oldest_generation() -> None:
    """Every tracked object into the oldest generation, in O(1) (`gc.freeze`
    then `gc.unfreeze`), so no young collection walks it once more; not
    while anything is frozen (unfreezing would undo that)."""
    if not gc.get_freeze_count():
        gc.freeze()
        gc.unfreeze()


def hold() -> None:
    """No collection until `release`: a command's start imports and loads
    what lives as long as the process (the `fastcs-ethercat` entry point
    holds it through the CLI's imports, the IOC through its own imports,
    configuration and terminal types). Released before anything that may
    wait long (the IOC's wait for an absent PLC collects as usual)."""
    global _holding
    if gc.isenabled():
        gc.disable()
        _holding = True


def release() -> None:
    """Collections resume if `hold` stopped them; what was built meanwhile
    goes to the oldest generation (it lives on)."""
    global _holding
    if _holding:
        _holding = False
        _to_oldest_generation()
        gc.enable()


@contextmanager
def held() -> Iterator[None]:
    """No collection within: for a bounded burst (one document's parse).

    What the burst built lives on (a parse result), so it goes straight to
    the oldest generation instead of being walked once more as young objects
    by the collection the next allocation would start: 25 ms of a full
    parse's 800, 60 ms when that is a middle-generation collection. Cyclic
    garbage of the burst (it makes none) would wait for a full collection.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            _to_oldest_generation()
            gc.enable()


def collect_rarely() -> None:
    """Young collections every `GC_THRESHOLD` objects (from the IOC's start:
    the collector still runs, so a long wait for the target leaks nothing)."""
    _, *older = gc.get_threshold()
    gc.set_threshold(GC_THRESHOLD, *older)


def pause() -> None:
    """No collection until `settle_garbage_collector`: the IOC's tree, its
    records and PVs are built in one burst once the chain is known, and
    each young collection in it (every `GC_THRESHOLD` objects) walked 50 000
    objects that all live on: ~0.1 s of a 104-terminal start."""
    gc.disable()


def settle_garbage_collector() -> None:
    """Once the IOC serves: what is built so far is moved out of the
    collector's sight (`gc.freeze`), else every full collection walks it all;
    collections resume (`pause`)."""
    gc.freeze()
    collect_rarely()
    gc.enable()


def freeze_new() -> None:
    """Objects made since (a first cycle's routes) live as long as the IOC."""
    gc.freeze()


__all__ = [
    "GC_THRESHOLD",
    "collect_rarely",
    "freeze_new",
    "held",
    "hold",
    "pause",
    "release",
    "settle_garbage_collector",
]
