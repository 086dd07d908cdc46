"""An IOC against a target without sum commands (simulator fault
`no_sum_commands`: 0xF080-0xF082 answered 0x701): it polls with single
requests at the configured rate, says so once, and uses sums again after a
reconnect to a target that has them.

1 008 changing symbols (28 EL3104s, Standard PDOs, counting up every task
cycle of 100 ms) polled at 10 Hz.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from fastcs_ethercat.bench.chains import scan_slaves, write_chain
from fastcs_ethercat.sim.process import SimProcess
from tests.ioc_support import IocProcess, caget, served_ioc, wait_for, write_ioc_config

pytestmark = pytest.mark.e2e

SYMBOLS = 1000
RATE_HZ = 10
SAID = "single requests"
VALUES = [f"ETH1:RIO1:MOD{n}:CH1:Value" for n in (2, 15, 29)]
RECONNECTED_S = 120.0
"""Generous: the reconnect (loss seen, rediscovery, 1 000 handles) takes
~0.5 s here, far longer on a host loaded by other test runs."""


def _root(ioc: IocProcess, name: str) -> str:
    pv = ioc.pv(name)
    return caget(ioc, "-S", pv).get(pv, "")


def _figure(ioc: IocProcess, name: str) -> float:
    text = _root(ioc, name)
    return float(text) if text else 0.0


def _values(ioc: IocProcess) -> list[str]:
    names = [ioc.pv(n) for n in VALUES]
    got = caget(ioc, *names)
    return [got.get(n, "") for n in names]


def _requests_by_group(sim: SimProcess, seconds: float) -> dict[str, int]:
    """ADS requests per index group the simulator served over `seconds`."""
    sim.reset_counters()
    time.sleep(seconds)
    return dict(sim.counters()["index_groups"])


def _said(ioc: IocProcess) -> list[str]:
    """The lines the IOC printed so far that say it uses single requests."""
    ioc.unread()
    return [line for line in ioc.output if SAID in line]


@pytest.mark.slow
def test_a_target_without_sum_commands_is_polled_with_single_requests(
    tmp_path: Path,
) -> None:
    chain = write_chain(
        tmp_path / "chain.yaml",
        scan_slaves(SYMBOLS, changing=True),
        task_cycle_ms=1000 / RATE_HZ,
    )

    def config(sim: SimProcess, prefix: str) -> Path:
        sim.add_fault("no_sum_commands")
        return write_ioc_config(
            tmp_path, prefix, sim.pyads_ip, sim.net_id, poll_rate_hz=RATE_HZ
        )

    with served_ioc("NOSUM", chain, config) as (sim, ioc):
        assert wait_for(lambda: _root(ioc, "InvalidPvs") == "0", 60)
        first = _values(ioc)
        single = _requests_by_group(sim, 2.0)
        later = _values(ioc)
        poll_rate = _figure(ioc, "PollRate")
        post_rate = _figure(ioc, "PostRate")
        said = _said(ioc)

        sim.clear_faults()  # sums served again, found by the next reconnect
        ioc.unread()
        sim.add_fault("drop")
        # the IOC's own word that it reconnected: not a statistic (posted once
        # a second, read by a caget that may time out on a loaded host)
        back = ioc.wait_for_line(r"target back: polling again", RECONNECTED_S)
        served = wait_for(
            lambda: (
                _root(ioc, "ConnectionState") == "CONNECTED"
                and _root(ioc, "InvalidPvs") == "0"
            ),
            RECONNECTED_S,
        )
        sums = _requests_by_group(sim, 1.0)
        said_after = _said(ioc)

    print(
        f"\nwithout sums: {poll_rate:.1f} polls/s, {post_rate:.0f} values "
        f"posted/s, requests in 2 s by group: {single}; after the reconnect, "
        f"in 1 s: {sums}"
    )
    assert back and served
    assert all(first) and all(later), (first, later)
    assert all(a != b for a, b in zip(first, later, strict=True)), (first, later)
    assert single.get("0xF080", 0) == 0 and single.get("0xF005", 0) > 0, single
    assert poll_rate > RATE_HZ / 2, poll_rate
    assert post_rate > SYMBOLS * RATE_HZ / 4, post_rate
    assert len(said) == 2, said  # sum reads and sum read-writes, once each
    assert sums.get("0xF080", 0) > 0 and sums.get("0xF005", 0) == 0, sums
    assert said_after == said
