"""The scan section: what polling costs with nothing changing, with every
value changing every cycle while a CA client monitors every PV, and what a
deadband saves on noisy analog values.

CPU is the IOC process's CPU time over wall time (all its threads: Python,
the CA and PVA servers), so other load on the machine slows it but does not
inflate it. With values changing it is taken twice: with no client connected
(what the first benchmarks printed: then the CA server sends nothing) and
while one client monitors every symbol PV and receives every update, the
figure a beamline sees (its archiver monitors most PVs).
"""

from __future__ import annotations

import asyncio
import statistics
import time
from dataclasses import dataclass
from typing import Any, Final

from aioca import caget

from fastcs_ethercat.bench.camon import updates_per_second
from fastcs_ethercat.bench.chains import NOISE_AMPLITUDE, scan_slaves
from fastcs_ethercat.bench.context import BenchContext
from fastcs_ethercat.bench.ioc_sections import (
    POLLING_TIMEOUT_S,
    PREFIX,
    SETTLE_S,
    SUM_READ_KEY,
    Running,
    running,
)
from fastcs_ethercat.bench.iocproc import loopback_env
from fastcs_ethercat.bench.monitor import MonitorClient, camonitor_binary
from fastcs_ethercat.bench.procstat import cpu_percent_over, cpu_seconds, peak_rss_mb
from fastcs_ethercat.sim.process import SimProcess

RATE_HZ: Final = 10.0
WARMUP_S: Final = 1.0
"""Monitoring before a window is measured (every channel has its first value)."""
DEADBAND: Final = 2.5 * NOISE_AMPLITUDE
"""The deadband of the noisy values: above their peak-to-peak noise."""


async def scan(context: BenchContext, symbols: int) -> dict[str, Any]:
    """Requests per cycle, IOC CPU unchanged / changing (with and without a
    monitoring client), updates received, at 10 Hz for about `symbols`."""
    plan = context.plan
    result: dict[str, Any] = {"target_symbols": symbols, "poll_rate_hz": RATE_HZ}
    slaves = scan_slaves(symbols, changing=False)
    async with running(context, f"scan-{symbols}-unchanged", slaves) as up:
        await _polling(up.sim)
        up.sim.reset_counters()
        start = time.monotonic()
        result["cpu_unchanged_pct"] = await _cpu_median(up, plan.runs, plan.window_s)
        cycles = (time.monotonic() - start) * RATE_HZ
        result["requests_per_cycle"] = round(up.sim.counters()["total"] / cycles, 2)
        result["symbols"] = len(up.symbol_pvs)
        result["rss_mb"] = round(peak_rss_mb(up.ioc.pid), 1)
    # One task cycle per poll: each poll sees new values, bits too (on a clock
    # a poll landing on a tick sees two cycles or none, and bits read the same).
    slaves = scan_slaves(symbols, changing=True)
    cycle_ms = 1000.0 / RATE_HZ
    name = f"scan-{symbols}-changing"
    async with running(
        context, name, slaves, task_cycle_ms=cycle_ms, cycle_per_poll=True
    ) as up:
        await _polling(up.sim)
        no_client = await _cpu_median(up, plan.runs, plan.window_s)
        result["cpu_changing_no_client_pct"] = no_client
        result.update(await monitored(up, plan.runs, plan.window_s))
    result["updates_per_s_ideal"] = round(result["symbols"] * RATE_HZ, 1)
    return result


async def deadband_effect(context: BenchContext, symbols: int) -> dict[str, Any]:
    """Noisy analog values (a few counts each cycle) monitored by a client,
    without a deadband and with one above the noise."""
    plan = context.plan
    slaves = scan_slaves(symbols, changing=False, noisy=True)
    result: dict[str, Any] = {
        "target_symbols": symbols,
        "noise_counts": NOISE_AMPLITUDE,
        "deadband": DEADBAND,
    }
    for label, deadbands in (("without", None), ("with", {"*.Value": DEADBAND})):
        name = f"deadband-{symbols}-{label}"
        async with running(context, name, slaves, deadbands=deadbands) as up:
            await _polling(up.sim)
            figures = await monitored(up, plan.runs, plan.window_s)
            result["symbols"] = len(up.symbol_pvs)
        for key in ("cpu_changing_pct", "updates_per_s", "updates_posted_per_s"):
            result[f"{key.removesuffix('_changing_pct')}_{label}"] = figures[key]
    return result


@dataclass
class Window:
    """One measured window with the client monitoring."""

    ioc_cpu_pct: float
    client_cpu_pct: float
    updates_per_s: float
    posted_per_s: float
    poll_rate_hz: float


async def monitored(up: Running, runs: int, window_s: float) -> dict[str, Any]:
    """IOC CPU and updates delivered while one client monitors every symbol
    PV (`bench.monitor`; aioca when camonitor is not installed)."""
    names = [pv.name for pv in up.symbol_pvs]
    binary = camonitor_binary()
    if binary is None:
        cpu = await _cpu_median(up, runs, window_s)
        received = await updates_per_second(names, window_s, warmup_s=WARMUP_S)
        return {
            "client": "aioca",
            "cpu_changing_pct": cpu,
            "updates_per_s": round(received, 1),
            "updates_posted_per_s": None,
        }
    with MonitorClient(names, loopback_env(), binary) as client:
        connected = await asyncio.to_thread(client.wait_connected, POLLING_TIMEOUT_S)
        if not connected:
            raise RuntimeError(f"camonitor connected {client.lines} of {len(names)}")
        await asyncio.sleep(WARMUP_S)
        windows = [await _window(up, client, window_s) for _ in range(runs)]
    posted = statistics.median(w.posted_per_s for w in windows)
    received = statistics.median(w.updates_per_s for w in windows)
    return {
        "client": "camonitor",
        "cpu_changing_pct": _median(w.ioc_cpu_pct for w in windows),
        "client_cpu_pct": _median(w.client_cpu_pct for w in windows),
        "updates_per_s": round(received, 1),
        "updates_posted_per_s": round(posted, 1),
        "updates_lost_per_s": round(max(0.0, posted - received), 1),
        "poll_rate_measured_hz": _median(w.poll_rate_hz for w in windows),
    }


async def _window(up: Running, client: MonitorClient, seconds: float) -> Window:
    """CPU of the IOC and the client, lines received, the IOC's own rates."""
    started = time.monotonic()
    ioc_cpu, client_cpu = cpu_seconds(up.ioc.pid), client.cpu_seconds()
    lines = client.lines
    rates = []
    while (left := started + seconds - time.monotonic()) > 0:
        await asyncio.sleep(min(left, 1.0))  # the IOC's rates are per second
        rates.append(await _ioc_rates())
    wall = time.monotonic() - started
    return Window(
        ioc_cpu_pct=100.0 * (cpu_seconds(up.ioc.pid) - ioc_cpu) / wall,
        client_cpu_pct=100.0 * (client.cpu_seconds() - client_cpu) / wall,
        updates_per_s=(client.lines - lines) / wall,
        posted_per_s=statistics.mean(posted for posted, _ in rates),
        poll_rate_hz=statistics.mean(polls for _, polls in rates),
    )


async def _ioc_rates() -> tuple[float, float]:
    """The IOC's own PostRate and PollRate PVs (over its last second)."""
    values: list[Any] = await caget(
        [f"{PREFIX}:PostRate", f"{PREFIX}:PollRate"], timeout=5.0
    )
    return float(values[0]), float(values[1])


async def _polling(sim: SimProcess) -> None:
    """Wait until the IOC's sum reads reach the simulator (polling started)."""
    deadline = time.monotonic() + POLLING_TIMEOUT_S
    sim.reset_counters()
    while sim.counters()["index_groups"].get(SUM_READ_KEY, 0) < 2:
        if time.monotonic() > deadline:
            raise RuntimeError(
                f"the IOC sent no sum reads within {POLLING_TIMEOUT_S:g} s"
            )
        await asyncio.sleep(0.05)
    await asyncio.sleep(2.0 / RATE_HZ + SETTLE_S)


async def _cpu_median(up: Running, windows: int, seconds: float) -> float:
    def measure() -> float:
        return _median(cpu_percent_over(up.ioc.pid, seconds) for _ in range(windows))

    return await asyncio.to_thread(measure)


def _median(values: Any) -> float:
    return round(statistics.median(values), 1)
