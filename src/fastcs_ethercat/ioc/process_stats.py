"""The IOC process's own health: when it started, how long ago, CPU, memory.

What devIocStats gives a C IOC, for the root controller's PVs (served on CA
and PVA alike, in PVI, the screens and `--list-pvs`). softioc ships
devIocStats' records, but only as CA records outside FastCS's tree (no PVA,
no PVI, no screen, not in the PV lists), and its template brings writable
records too (`SYSRESET` restarts the IOC on one caput, `*_UPD_TIME` change
its scan periods), which a read-only IOC must not serve.
"""

from __future__ import annotations

import os
import resource
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

STATM: Final = Path("/proc/self/statm")
"""Linux: the process's pages; the second field is its resident set."""
MIB: Final = 1024 * 1024
DEVIOCSTATS_NAMES: Final = {
    "UptimeText": "UPTIME",
    "Heartbeat": "HEARTBEAT",
    "IocCpuLoad": "IOC_CPU_LOAD",
    "MemUsedBytes": "MEM_USED",
    "StartCount": "START_CNT",
}
"""The root's PVs with devIocStats' meaning -> devIocStats' names, served as
record aliases: on CA, and on PVA too (QSRV serves a record's aliases)."""


def deviocstats_aliases(prefix: str) -> dict[str, str]:
    """The record aliases (full PV -> alias) of `DEVIOCSTATS_NAMES`, given to
    FastCS's CA transport, whose records QSRV also serves."""
    return {
        f"{prefix}:{ours}": f"{prefix}:{theirs}"
        for ours, theirs in DEVIOCSTATS_NAMES.items()
    }


@dataclass(frozen=True)
class ProcessSample:
    """One reading of the process."""

    uptime_s: float
    cpu_percent: float
    """Of one core since the previous reading (100 % = one core busy)."""
    memory_mib: float
    """Resident set now (Linux), else the peak resident set."""

    @property
    def cpu_percent_of_all(self) -> float:
        """Of every core this process may run on (devIocStats' IOC_CPU_LOAD)."""
        return self.cpu_percent / usable_cores()

    @property
    def memory_bytes(self) -> float:
        """`memory_mib` in bytes (devIocStats' MEM_USED)."""
        return self.memory_mib * MIB

    @property
    def uptime_text(self) -> str:
        """devIocStats' UPTIME: `3 days, 04:05:06`."""
        return uptime_text(self.uptime_s)


@dataclass
class ProcessStats:
    """Reads the process's uptime, CPU and memory; CPU as a rate between
    consecutive readings."""

    started: float = field(default_factory=time.time)
    """time.time() at start (the IOC's start time)."""
    _wall: float = field(default_factory=time.monotonic)
    _cpu: float = field(default_factory=time.process_time)
    _started_monotonic: float = field(default_factory=time.monotonic)

    def sample(self) -> ProcessSample:
        wall, cpu = time.monotonic(), time.process_time()
        elapsed = wall - self._wall
        percent = 100.0 * (cpu - self._cpu) / elapsed if elapsed > 0 else 0.0
        self._wall, self._cpu = wall, cpu
        return ProcessSample(
            uptime_s=wall - self._started_monotonic,
            cpu_percent=max(percent, 0.0),
            memory_mib=resident_mib(),
        )

    def start_text(self) -> str:
        """The start time as operators read it: `2026-12-01 16:02:50`."""
        return time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.started))


def uptime_text(seconds: float) -> str:
    """`seconds` as devIocStats writes its UPTIME: `D days, HH:MM:SS`."""
    minutes, secs = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    days, hours = divmod(hours, 24)
    return f"{days} days, {hours:02d}:{minutes:02d}:{secs:02d}"


def usable_cores() -> int:
    """The cores this process may run on (its affinity, else the machine's)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):
        return max(os.cpu_count() or 1, 1)


def resident_mib() -> float:
    """The process's resident memory in MiB."""
    try:
        pages = int(STATM.read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / MIB
    except (OSError, ValueError, IndexError):
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return peak / MIB if sys.platform == "darwin" else peak / 1024
