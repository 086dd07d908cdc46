"""The IOC process's own figures: uptime, CPU, memory, start time."""

from __future__ import annotations

import time

from fastcs_ethercat.ioc.process_stats import ProcessStats, resident_mib


def test_cpu_is_a_rate_between_readings_and_memory_is_resident() -> None:
    stats = ProcessStats()
    stats.sample()
    busy_until = time.monotonic() + 0.2
    while time.monotonic() < busy_until:  # one core busy for 0.2 s
        sum(range(1000))
    busy = stats.sample()
    time.sleep(0.2)
    idle = stats.sample()

    assert busy.cpu_percent > 5  # a loaded machine lends less than a core
    assert idle.cpu_percent < busy.cpu_percent
    assert idle.uptime_s >= 0.4
    assert busy.memory_mib > 10
    assert abs(resident_mib() - busy.memory_mib) < 50


def test_start_time_reads_as_local_time() -> None:
    stats = ProcessStats(started=0.0)
    text = stats.start_text()

    assert time.mktime(time.strptime(text, "%Y-%m-%d %H:%M:%S")) == 0.0
