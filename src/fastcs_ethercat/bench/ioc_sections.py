"""The runtime half: the simulator and the IOC in their own processes, a CA
client here. Start-up time, requests and CPU per poll cycle, monitor updates
received, change-to-event latency, peak memory."""

from __future__ import annotations

import asyncio
import os
import statistics
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aioca import purge_channel_caches

from fastcs_ethercat.ads.constants import IndexGroup
from fastcs_ethercat.bench.camon import (
    change_latencies_ms,
    connect_all,
    percentiles,
)
from fastcs_ethercat.bench.chains import (
    demo_mix,
    mixed_slaves,
    scan_slaves,
    terminals_with_coe,
    write_chain,
)
from fastcs_ethercat.bench.context import BenchContext
from fastcs_ethercat.bench.iocproc import (
    IocProcess,
    PvLine,
    list_pvs,
    write_ioc_config,
)
from fastcs_ethercat.bench.procstat import peak_rss_mb
from fastcs_ethercat.sim.process import SimProcess

SETTLE_S = 1.0
"""Polling after every PV connected, before peak memory is read."""
POLLING_TIMEOUT_S = 30.0
PREFIX = f"BN{os.getpid() % 1000:03d}"
"""Five characters like "BENCH", and this run's own: two benchmark runs (or a
test) on one host must not serve the same PV names."""
SUM_READ_KEY = f"0x{IndexGroup.SUMUP_READ:X}"
"""The simulator's counter key of sum reads (0xF080)."""


@dataclass
class Running:
    """A simulator and an IOC serving it, plus the IOC's PV list."""

    sim: SimProcess
    ioc: IocProcess
    pvs: list[PvLine]

    @property
    def symbol_pvs(self) -> list[PvLine]:
        return [pv for pv in self.pvs if pv.is_symbol]


@asynccontextmanager
async def running(
    context: BenchContext,
    name: str,
    slaves: list[dict[str, Any]],
    *,
    poll_rate_hz: float = 10.0,
    task_cycle_ms: float = 10.0,
    cycle_per_poll: bool = False,
    terminals: Path | None = None,
    timed_start: bool = False,
    deadbands: dict[str, float] | None = None,
) -> AsyncIterator[Running]:
    """Start the simulator with a generated chain and the IOC against it.

    The PV list comes from `ioc --list-pvs`: before the IOC starts when its
    start is timed, else at the same time (quicker)."""
    terminals = terminals or context.terminals
    chain = write_chain(
        context.scratch / f"{name}-chain.yaml", slaves, task_cycle_ms=task_cycle_ms
    )
    config = write_ioc_config(
        context.scratch / f"{name}-ioc.yaml",
        prefix=PREFIX,
        terminals=terminals,
        poll_rate_hz=poll_rate_hz,
        deadbands=deadbands,
    )
    timeout = context.plan.start_timeout_s
    extra_args = ["--cycle-per-poll"] if cycle_per_poll else []
    with SimProcess(chain=chain, terminals=terminals, extra_args=extra_args) as sim:
        listing = asyncio.to_thread(list_pvs, config, sim.pyads_ip, sim.net_id, timeout)
        with IocProcess(config, sim.pyads_ip, sim.net_id) as ioc:
            if timed_start:  # nothing else may load the machine while it starts
                pvs = await listing
                await asyncio.to_thread(ioc.start, timeout)
            else:
                pvs, _ = await asyncio.gather(
                    listing, asyncio.to_thread(ioc.start, timeout)
                )
            try:
                yield Running(sim, ioc, pvs)
            finally:
                # Close our channels before the server goes: no disconnect
                # noise, and the next IOC (same names) gets fresh channels.
                purge_channel_caches()


async def ioc_start(context: BenchContext, terminals: int, coe: bool) -> dict[str, Any]:
    """Launch to every PV connectable (median of runs) and peak RSS."""
    directory = context.terminals
    if coe:
        directory = terminals_with_coe(
            context.terminals, context.scratch / "terminals-coe"
        )
    slaves = mixed_slaves(terminals, demo_mix(context.demo_chain))
    starts: list[float] = []
    readies: list[float] = []
    rss: list[float] = []
    pv_count = 0
    # CoE start-ups read every object over SDO: one run each is enough.
    for run in range(1 if coe else context.plan.runs):
        name = f"start-{terminals}-{'coe' if coe else 'plain'}-{run}"
        async with running(
            context, name, slaves, terminals=directory, timed_start=True
        ) as up:
            deadline = up.ioc.started_at + context.plan.start_timeout_s
            connected = await connect_all([pv.name for pv in up.pvs], deadline)
            if connected is None:
                raise RuntimeError(f"not every PV connected: {up.ioc.log_tail()}")
            assert up.ioc.ready_at is not None
            starts.append(connected - up.ioc.started_at)
            readies.append(up.ioc.ready_at - up.ioc.started_at)
            await asyncio.sleep(SETTLE_S)
            rss.append(peak_rss_mb(up.ioc.pid))
            pv_count = len(up.pvs)
    return {
        "terminals": terminals,
        "coe": coe,
        "pvs": pv_count,
        "start_s": round(statistics.median(starts), 3),
        "ready_line_s": round(statistics.median(readies), 3),
        "rss_mb": round(statistics.median(rss), 1),
        "runs": len(starts),
    }


async def latency(context: BenchContext, rate_hz: float) -> dict[str, Any]:
    """Simulator value change (control API) to CA monitor event."""
    slaves = scan_slaves(5 * 36, changing=False)
    async with running(
        context, f"latency-{rate_hz:g}", slaves, poll_rate_hz=rate_hz
    ) as up:
        pv = next(
            p for p in up.symbol_pvs if p.source.endswith(".Value") and p.type == "Int"
        )
        latencies, round_trips = await change_latencies_ms(
            pv.name,
            lambda value: up.sim.set_symbol(pv.source, value),
            samples=context.plan.latency_samples,
            period_s=1.0 / rate_hz,
        )
    figures = percentiles(latencies)
    return {
        **figures,
        "poll_period_ms": round(1000.0 / rate_hz, 1),
        "samples": len(latencies),
        "control_rtt_ms": percentiles(round_trips)["p50"],
        "pv": pv.name,
    }
