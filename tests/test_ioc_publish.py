"""The publish path end to end: a poll cycle's values written to their CA
records under one lock and posted to PVA only while a client listens.

The IOC (tests/data/publish_ioc.py) runs in a subprocess on free loopback
ports, publishes batches through `Health` as the poll cycles do, and takes
commands on stdin; real clients read the result: `caget -a`, `caput`, p4p.
"""

from __future__ import annotations

import queue
import sys
import time
from collections.abc import Iterator
from datetime import datetime
from typing import Any

import pytest

from tests.conftest import TEST_DATA
from tests.ioc_support import (
    START_TIMEOUT,
    IocProcess,
    caget,
    command,
    ioc_env,
    new_token,
    start_ioc,
    wait_for,
)

pytestmark = pytest.mark.e2e

NAMES = ("Temperature", "Counts", "Flag", "Mode", "Text")


@pytest.fixture(scope="module")
def ioc() -> Iterator[IocProcess]:
    token = new_token()
    prefix = f"PUB{token[:6].upper()}"
    env = ioc_env(token)
    started = start_ioc(
        [sys.executable, str(TEST_DATA / "publish_ioc.py"), "--prefix", prefix],
        prefix,
        env,
        token,
        commands=True,
    )
    try:
        started.wait_for_line("publish ioc ready", START_TIMEOUT)
        first = started.pv("Counts")
        assert wait_for(lambda: first in caget(started, first), START_TIMEOUT)
        yield started
    finally:
        started.stop()


def publish(ioc: IocProcess, **values: str) -> int:
    pairs = " ".join(f"{name}={value}" for name, value in values.items())
    return command(ioc, f"publish {pairs}")


def ca_lines(ioc: IocProcess, *names: str) -> dict[str, list[str]]:
    """`caget -a -S` words after the name: date, time, value..., [STAT SEVR]."""
    found = caget(ioc, "-a", "-S", *(ioc.pv(name) for name in names))
    return {name: found[ioc.pv(name)].split() for name in names}


def pva_get(ioc: IocProcess, *names: str) -> dict[str, dict[str, Any]]:
    with ioc.p4p_context() as context:
        values: Any = context.get([ioc.pv(name) for name in names], timeout=10)
    return {
        name: getattr(value, "raw", value).todict()
        for name, value in zip(names, values, strict=True)
    }


def ca_stamp(words: list[str]) -> float:
    """The time of a `caget -a` line (its first two words, local time)."""
    text = " ".join(words[:2])
    return datetime.strptime(text, "%Y-%m-%d %H:%M:%S.%f").timestamp()


def pva_stamp(value: dict[str, Any]) -> float:
    stamp = value["timeStamp"]
    return stamp["secondsPastEpoch"] + stamp["nanoseconds"] * 1e-9


def test_a_batch_posts_every_value_when_it_is_posted(ioc: IocProcess) -> None:
    """Each record's time is its processing's (TSE 0): the batch's values
    are processed together, right after the read (here: the command)."""
    before = time.time()
    posted = publish(
        ioc, Temperature="21.5", Counts="7", Flag="1", Mode="RUN",
        Text="hi",
    )  # fmt: skip
    after = time.time()
    on_ca = ca_lines(ioc, *NAMES)
    on_pva = pva_get(ioc, *NAMES)

    assert posted == 5
    assert {name: words[2] for name, words in on_ca.items()} == {
        "Temperature": "21.5",
        "Counts": "7",
        "Flag": "True",
        "Mode": "RUN",
        "Text": "hi",
    }
    ca_times = [ca_stamp(words) for words in on_ca.values()]
    pva_times = [pva_stamp(v) for v in on_pva.values()]
    assert all(len(words) == 3 for words in on_ca.values()), on_ca  # no alarm
    assert on_pva["Temperature"]["value"] == 21.5
    assert on_pva["Counts"]["value"] == 7
    assert on_pva["Mode"]["value"]["index"] == 1
    assert all(before <= t <= after for t in ca_times + pva_times), (before, after)
    assert max(pva_times) - min(pva_times) < 0.5  # one batch, processed together


def test_pva_clients_see_the_newest_value_when_they_connect(ioc: IocProcess) -> None:
    """No client: the cycles' values wait in the IOC; a get, a monitor that
    starts later and one after the last client left all get the newest."""
    now = time.time()
    for step in range(5):
        publish(ioc, Counts=str(100 + step))
    last_posted = time.time()
    fresh = pva_get(ioc, "Counts")["Counts"]
    received: queue.Queue[tuple[int, float]] = queue.Queue()
    with ioc.p4p_context() as context:
        subscription = context.monitor(
            ioc.pv("Counts"),
            lambda value: received.put((int(value), value.timestamp)),
        )
        first = received.get(timeout=10)
        publish(ioc, Counts="200")
        second = received.get(timeout=10)
        subscription.close()
    time.sleep(0.5)  # the server sees the last client go
    publish(ioc, Counts="300")
    after = pva_get(ioc, "Counts")["Counts"]

    assert fresh["value"] == 104 and now <= pva_stamp(fresh) <= last_posted
    assert first[0] == 104 and round(first[1], 6) == round(pva_stamp(fresh), 6)
    assert second[0] == 200 and second[1] > first[1]
    assert after["value"] == 300 and pva_stamp(after) > second[1]


def test_an_alarm_lands_on_the_newest_value(ioc: IocProcess) -> None:
    publish(ioc, Temperature="5.25")
    command(ioc, "alarm Temperature INVALID COMM")
    alarmed = pva_get(ioc, "Temperature")["Temperature"]
    on_ca = ca_lines(ioc, "Temperature")["Temperature"]
    command(ioc, "clear Temperature")
    cleared = pva_get(ioc, "Temperature")["Temperature"]

    assert alarmed["value"] == 5.25
    assert alarmed["alarm"]["severity"] == 3
    assert on_ca[2:] == ["5.25", "COMM", "INVALID"], on_ca
    assert cleared["value"] == 5.25 and cleared["alarm"]["severity"] == 0


def test_a_value_that_fails_stops_no_other(ioc: IocProcess) -> None:
    posted = publish(ioc, Counts="5000", Temperature="1.5")
    failures = [line for line in ioc.output if line.startswith("failure ")]

    assert posted == 1
    assert failures == ["failure Counts: Value 5000 is greater than maximum 1000\n"]
    assert ca_lines(ioc, "Temperature")["Temperature"][2] == "1.5"


def test_nan_is_undefined_on_ca_until_a_number_comes(ioc: IocProcess) -> None:
    publish(ioc, Temperature="nan")
    undefined = ca_lines(ioc, "Temperature")["Temperature"]
    publish(ioc, Temperature="2.5")
    defined = ca_lines(ioc, "Temperature")["Temperature"]

    assert undefined[-2:] == ["UDF", "INVALID"], undefined
    assert defined[2:] == ["2.5"], defined


def test_processing_a_record_keeps_its_value(ioc: IocProcess) -> None:
    """A client's PROC processes the record as it is: the value put last
    stays (a soft input record with no INP keeps its VAL), at a new time."""
    publish(ioc, Counts="42")
    publish(ioc, Counts="43")
    posted = ca_stamp(ca_lines(ioc, "Counts")["Counts"])
    ioc.tool("caput", ioc.pv("Counts.PROC"), "1")
    after = ca_lines(ioc, "Counts")["Counts"]

    assert after[2] == "43"
    assert ca_stamp(after) >= posted
