"""`sim --cycle-per-poll`: the task advances one cycle per poll of a client,
whatever the phase between the two, so a bit that toggles every cycle reads
differently at every poll (what `bench` needs to offer every value changed)."""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator

import pyads
import pytest
import yaml

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT

pytestmark = pytest.mark.e2e

NET_ID = "192.0.2.64.1.1"
CYCLE_S = 0.1
TOGGLE = "Term 22 (EL3104).AI Standard Channel 1.Status.TxPDO Toggle"
"""Counts up one a cycle: a one-bit counter."""


@pytest.fixture(scope="module")
def device(tmp_path_factory: pytest.TempPathFactory) -> Iterator[pyads.Connection]:
    chain = yaml.safe_load((REPO_ROOT / "ioc" / "demo-chain.yaml").read_text())
    chain["system"]["net_id"] = NET_ID
    path = tmp_path_factory.mktemp("chain") / "chain.yaml"
    path.write_text(yaml.safe_dump(chain, sort_keys=False))
    args = ["--cycle-per-poll", "--cycle-ms", str(CYCLE_S * 1000)]
    with SimProcess(path, terminals=REPO_ROOT / "terminals", extra_args=args) as sim:
        connection = pyads.Connection(NET_ID, 27905, sim.pyads_ip)
        connection.open()
        connection.set_timeout(5000)
        try:
            yield connection
        finally:
            connection.close()


def _polls(device: pyads.Connection, pauses: list[float]) -> list[bool]:
    """The toggle read once after each pause."""
    values = []
    for pause in pauses:
        time.sleep(pause)
        values.append(bool(device.read_by_name(TOGGLE, pyads.PLCTYPE_BOOL)))
    return values


def test_every_poll_sees_one_new_cycle_whatever_its_phase(
    device: pyads.Connection,
) -> None:
    # Polls a cycle apart, give or take a quarter: on a clock, a poll landing
    # on a tick would see two cycles or none and read the toggle unchanged.
    pauses = [CYCLE_S * factor for factor in (1.0, 0.8, 1.2, 1.0, 0.9, 1.1, 1.0)]
    values = _polls(device, [CYCLE_S, *pauses])
    assert all(a != b for a, b in itertools.pairwise(values)), values


def test_requests_within_a_poll_see_the_same_cycle(device: pyads.Connection) -> None:
    values = _polls(device, [CYCLE_S, 0.0, 0.01, 0.02])
    assert len(set(values)) == 1, values
