"""Start-up pieces in process: a supervisor that starts without its target,
what a first live discovery says against the chain served before it, and
start-up warnings folded across the terminals of a rack."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass, field

import pytest

from fastcs_ethercat.ads.ethercat import SlaveIdentity
from fastcs_ethercat.ioc.controllers.root import fold_by_terminal
from fastcs_ethercat.ioc.plan import (
    MasterPlan,
    Point,
    PointKind,
    SlaveInfo,
    SystemPlan,
    TerminalPlan,
)
from fastcs_ethercat.ioc.reconnect import chain_changes
from fastcs_ethercat.ioc.supervisor import Backoff, LinkState, Probe, Supervisor


@dataclass
class FlakyLink:
    """A target that refuses `failures` reconnects, then answers."""

    failures: int
    calls: list[str] = field(default_factory=list)

    async def lost(self, reason: str) -> None:
        self.calls.append("lost")

    async def stopped(self, ads_state: int) -> None:
        self.calls.append("stopped")

    async def reconnect(self) -> int:
        self.calls.append("reconnect")
        if self.failures:
            self.failures -= 1
            raise ConnectionRefusedError("connection refused")
        return 7

    async def resync(self, why: str) -> int:
        self.calls.append("resync")
        return 7


async def test_a_supervisor_without_its_target_reconnects_first(
    caplog: pytest.LogCaptureFixture,
) -> None:
    link = FlakyLink(failures=5)

    async def probe() -> Probe:
        return Probe(5, 7)  # RUN, the version reconnect returned

    supervisor = Supervisor(
        probe,
        link,
        0,
        period_s=0.01,
        backoff=Backoff(first_s=0.01, most_s=0.01),
        connected=False,
    )
    assert supervisor.state is LinkState.DISCONNECTED
    with caplog.at_level(logging.INFO):
        task = asyncio.create_task(supervisor.run())
        while supervisor.state is not LinkState.CONNECTED:
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.05)
        task.cancel()

    assert link.calls == ["reconnect"] * 6  # no loss, no resync: found once
    assert supervisor.symbol_version == 7
    assert supervisor.stats.losses == 0 and supervisor.stats.reconnects == 1
    failed = [r for r in caplog.records if "reconnect failed" in r.getMessage()]
    assert len(failed) == 1  # five failures, one line (at most one per 10 s)
    assert "target answers" in caplog.text and "target back" not in caplog.text


def _point(master: str, symbol: str) -> Point:
    return Point(f"{master}/{symbol}", symbol, "v", "INT", PointKind.SCALAR, 0, 0, 2)


def _plan(slaves: dict[int, list[str]]) -> SystemPlan:
    master = MasterPlan(1, "Device 1 (EtherCAT)", "5.1.2.3.2.1", 27905)
    for address, symbols in slaves.items():
        name = f"Term {address - 1000} (EL3104)"
        terminal = TerminalPlan(
            SlaveInfo(address, name, SlaveIdentity(2, 3, 0x100000)), "EL3104"
        )
        terminal.points = [_point(master.name, f"{name}.{s}") for s in symbols]
        master.terminals.append(terminal)
    return SystemPlan("5.1.2.3.1.1", "", "", 0, [master])


def test_live_points_the_served_chain_lacks_are_counted() -> None:
    served = _plan({1001: ["AI Standard Channel 1"]})
    live = _plan({1001: ["AI Compact Channel 1", "AI Compact Channel 2"], 1002: ["A"]})

    changes = chain_changes(served, live)

    assert changes[0].startswith("Device 1 (EtherCAT) slave 1002 new")
    assert changes[1] == "2 live points not served until restart"  # not 1002's
    assert chain_changes(served, served) == []


def test_warnings_alike_on_many_terminals_are_one_line() -> None:
    names = [f"Term {k} (EL3104)" for k in (5, 29, 53, 77, 101)]
    group = "the PLC runs PDO group 'Compact', the YAML selects 'Standard'"
    warnings = [
        f"{names[0]}: {group}",
        "alias matches nothing: X",
        *(f"{name}: {group}" for name in names[1:]),
        f"{names[2]}: revision 0x00100000 has no YAML",
    ]

    folded = fold_by_terminal(warnings, set(names))

    assert folded == [
        "5 terminals (Term 5 (EL3104), Term 29 (EL3104), Term 53 (EL3104) and 2 "
        f"more): {group}",
        "alias matches nothing: X",
        "Term 53 (EL3104): revision 0x00100000 has no YAML",
    ]
