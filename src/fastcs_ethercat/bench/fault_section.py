"""Fault timings: how soon a fault shows on the PVs (INVALID) and how soon
they are valid again once it is gone, and how soon an IOC started without
its PLC serves live values once the PLC appears.

The faults: the whole target lost (stalled, connection dropped), one slave
out of OP or its link lost (seen through the master's diagnostics, read
once a second), and an online change that takes the slave's PDOs away
(another PDO group) and brings them back.

The targets are the benchmark's (`report.py`); the end-to-end tests assert
only the behaviour (INVALID, then valid again) within generous bounds.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from functools import partial
from typing import Any, Final

from aioca import FORMAT_TIME, camonitor, connect, purge_channel_caches

from fastcs_ethercat.bench.chains import scan_slaves
from fastcs_ethercat.bench.context import BenchContext
from fastcs_ethercat.bench.ioc_sections import PREFIX, running
from fastcs_ethercat.bench.iocproc import IocProcess, write_ioc_config
from fastcs_ethercat.process import free_port
from fastcs_ethercat.sim.process import SimProcess

INVALID: Final = 3
WAIT_S: Final = 30.0
"""Longest wait for a state; beyond it the figure is an error."""
FAULTS: Final = (("stall", 2.0), ("drop", 0.0))
"""(fault, seconds it lasts) as the end-to-end tests inject them."""
FAULTED_SLAVE: Final = "Term 2 (EL3104)"
"""The scan chain's one EL3104 (behind its coupler), named as TwinCAT does."""
SLAVE_FAULTS: Final = (
    ("slave_preop", {"kind": "slave_state", "state": "PREOP"}),
    ("link_lost", {"kind": "link_lost"}),
)
"""(figure, fault of `FAULTED_SLAVE`), each until cleared."""
OTHER_PDO_GROUP: Final = "Compact"
"""Activated by the online change: the PV's PDOs (the chain's "Standard"
group, `chains.scan_slaves`) are gone until the next change restores them."""


class SeverityWatch:
    """Every CA monitor update of one PV: (monotonic time, severity)."""

    def __init__(self, pv: str) -> None:
        self.pv = pv
        self.updates: list[tuple[float, int]] = []
        self._subscription = camonitor(
            pv, self._on_update, format=FORMAT_TIME, all_updates=True
        )

    def _on_update(self, value: Any) -> None:
        self.updates.append((time.monotonic(), int(value.severity)))

    async def first(self, since: float, invalid: bool) -> float:
        """Seconds from `since` to the first update INVALID (or not)."""
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            for stamp, severity in self.updates:
                if stamp >= since and (severity == INVALID) == invalid:
                    return round(stamp - since, 3)
            await asyncio.sleep(0.01)
        state = "INVALID" if invalid else "valid"
        raise TimeoutError(f"{self.pv} not {state} within {WAIT_S:.0f} s")

    def close(self) -> None:
        self._subscription.close()


async def fault_timings(context: BenchContext) -> dict[str, Any]:
    """Per fault: loss (fault to INVALID) and recovery (gone to valid)."""
    figures: dict[str, Any] = {}
    slaves = scan_slaves(36, changing=True)
    slaves[1]["name"] = FAULTED_SLAVE
    async with running(context, "faults", slaves) as up:
        pv = next(p for p in up.symbol_pvs if p.source.endswith(".Value")).name
        await connect(pv, timeout=10.0)
        watch = SeverityWatch(pv)
        sim = up.sim
        try:
            await watch.first(time.monotonic(), invalid=False)
            for kind, lasts_s in FAULTS:
                inject = partial(sim.add_fault, kind)
                figures[kind] = await _outage(watch, inject, sim.clear_faults, lasts_s)
            for name, fault in SLAVE_FAULTS:
                inject = partial(sim.add_fault, **fault, name=FAULTED_SLAVE)
                figures[name] = await _outage(watch, inject, sim.clear_faults)
            change = partial(sim.add_fault, "online_change")
            figures["pdo_change"] = await _outage(
                watch,
                partial(change, pdo_groups={FAULTED_SLAVE: OTHER_PDO_GROUP}),
                partial(change, pdo_groups={FAULTED_SLAVE: "Standard"}),
            )
        finally:
            watch.close()
        net_id = sim.net_id
    figures["plc_appears"] = await plc_appears(context, pv, net_id)
    return figures


async def _outage(
    watch: SeverityWatch,
    inject: Callable[[], object],
    end: Callable[[], object],
    lasts_s: float = 0.0,
) -> dict[str, float]:
    """`inject` a fault, wait for INVALID, `end` it after `lasts_s` at the
    earliest, wait for valid: seconds to each (control calls in a thread)."""
    start = time.monotonic()
    await asyncio.to_thread(inject)
    loss = await watch.first(start, invalid=True)
    await asyncio.sleep(max(0.0, lasts_s - (time.monotonic() - start)))
    ended = time.monotonic()
    await asyncio.to_thread(end)
    since = max(ended, start + loss)  # valid again after the loss
    back = await watch.first(since, invalid=False) + (since - ended)
    return {"loss_s": loss, "recovery_s": round(back, 3)}


async def plc_appears(context: BenchContext, pv: str, net_id: str) -> dict[str, Any]:
    """An IOC serving the chain file (its PLC away), then the PLC: seconds
    from the simulator's ready line to the PV valid."""
    purge_channel_caches()
    chain = context.scratch / "faults-chain.yaml"  # written by `running`
    config = write_ioc_config(
        context.scratch / "boot-ioc.yaml",
        prefix=PREFIX,
        terminals=context.terminals,
        poll_rate_hz=10.0,
        chain=chain,
    )
    port = free_port(tcp=True, udp=False)
    with IocProcess(config, f"127.0.0.1:{port}", net_id) as ioc:
        await asyncio.to_thread(ioc.start, context.plan.start_timeout_s)
        await connect(pv, timeout=10.0)
        watch = SeverityWatch(pv)
        try:
            served_invalid = await watch.first(time.monotonic() - WAIT_S, True)
            with SimProcess(chain=chain, terminals=context.terminals, port=port):
                appeared = time.monotonic()
                live = await watch.first(appeared, invalid=False)
        finally:
            watch.close()
            purge_channel_caches()
    return {"served_invalid": served_invalid >= 0, "live_s": live}
