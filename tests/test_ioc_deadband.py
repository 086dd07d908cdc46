"""Deadbands: configured by symbol pattern, applied as MDEL is when publishing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from fastcs.attributes import AttrR
from fastcs.datatypes import Bool, Float, Int

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc import publish
from fastcs_ethercat.ioc.attributes import PointRef
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.ioc.deadband import Deadbands
from fastcs_ethercat.ioc.plan import Point, PointKind
from fastcs_ethercat.ioc.publish import Publisher

VALUE = "Term 5 (EL3104).AI Standard Channel 1.Value"
RULES = Deadbands.of_config(
    {
        "Term 5 (EL3104).AI Standard Channel 1.*": 10,
        "*(EL3104).AI Standard Channel *.Value": 3,
    }
)


def polled(symbol: str, datatype: Any) -> AttrR[Any, Any]:
    point = Point(
        key=f"ETH1/1005/{symbol}",
        symbol=symbol,
        attribute="value",
        type_name="INT",
        kind=PointKind.SCALAR,
        index_group=0xF020,
        index_offset=0,
        byte_size=2,
    )
    return AttrR(datatype, io_ref=PointRef(point))


def test_the_first_matching_pattern_gives_the_deadband() -> None:
    assert RULES.of_symbol(VALUE) == 10
    assert RULES.of_symbol("Term 9 (EL3104).AI Standard Channel 4.Value") == 3
    assert RULES.of_symbol("Term 9 (EL3104).AI Standard Channel 4.Status") == 0
    assert Deadbands().of_symbol(VALUE) == 0


def test_only_polled_numbers_have_a_deadband() -> None:
    assert RULES.of_attribute(polled(VALUE, Int())) == 10
    assert RULES.of_attribute(polled(VALUE, Float())) == 10
    assert RULES.of_attribute(polled(VALUE, Bool())) == 0
    assert RULES.of_attribute(AttrR(Int())) == 0  # not polled: no symbol


@pytest.fixture
async def started(monkeypatch: pytest.MonkeyPatch) -> Publisher:
    # the collector settings are for an IOC process, not the test session
    monkeypatch.setattr(publish, "settle_garbage_collector", lambda: None)
    publisher = Publisher(Deadbands.of_config({"*.Value": 3}))
    await publisher.start()
    return publisher


async def test_a_value_is_posted_when_it_moved_beyond_the_deadband(
    started: Publisher,
) -> None:
    """As MDEL: compared with the value posted last, not the one read last."""
    noisy = polled(VALUE, Int())
    plain = polled("Term 5 (EL3104).AI Standard Channel 1.Status", Int())
    shown = []
    for value in (100, 102, 103, 104, 106, 101, 100):
        await started.publish_batch([(noisy, value), (plain, value)])
        shown.append((noisy.get(), plain.get()))

    noisy_shown = [noisy_value for noisy_value, _ in shown]
    plain_shown = [plain_value for _, plain_value in shown]
    assert noisy_shown == [100, 100, 100, 104, 104, 104, 100]
    assert plain_shown == [100, 102, 103, 104, 106, 101, 100]
    assert started.within_deadband == 4
    assert started.posted == 3 + 7


def test_config_deadbands_are_patterns_to_non_negative_numbers(tmp_path: Path) -> None:
    path = tmp_path / "ioc.yaml"
    path.write_text(
        "prefix: T\ntarget: localhost\n"
        'deadbands:\n  "*(EL3104).AI Standard Channel *.Value": 4\n  "*.Counter": 0.5\n'
    )
    config = load_ioc_config(path)
    path.write_text('prefix: T\ntarget: localhost\ndeadbands:\n  "*.Value": -1\n')
    with pytest.raises(UserError) as error:
        load_ioc_config(path)

    assert Deadbands.of_config(config.deadbands).rules == (
        ("*(EL3104).AI Standard Channel *.Value", 4.0),
        ("*.Counter", 0.5),
    )
    assert "deadbands" in str(error.value) and "greater than or equal to 0" in str(
        error.value
    )
