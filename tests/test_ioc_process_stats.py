"""The IOC process's own figures: uptime, CPU, memory, start time."""

from __future__ import annotations

import asyncio
import os
import time
from pathlib import Path

import pytest

from fastcs_ethercat.ioc import heartbeat as heartbeat_module
from fastcs_ethercat.ioc.heartbeat import Heartbeat, count_start
from fastcs_ethercat.ioc.process_stats import (
    ProcessSample,
    ProcessStats,
    resident_mib,
    uptime_text,
    usable_cores,
)


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


def test_deviocstats_uptime_text_and_load_of_all_cores() -> None:
    sample = ProcessSample(
        uptime_s=3 * 86400 + 4 * 3600 + 5 * 60 + 6.9, cpu_percent=100.0, memory_mib=2.0
    )

    assert sample.uptime_text == uptime_text(sample.uptime_s) == "3 days, 04:05:06"
    assert sample.cpu_percent_of_all == 100.0 / usable_cores()
    assert sample.memory_bytes == 2 * 1024 * 1024


def test_heartbeat_file_holds_pid_count_and_time(tmp_path: Path) -> None:
    path = tmp_path / "heartbeat"
    heartbeat = Heartbeat(path)
    at_start = path.read_text().split()
    heartbeat.beat()
    pid, count, stamp = path.read_text().split()

    assert at_start[:2] == [str(os.getpid()), "0"]
    assert (int(pid), int(count)) == (os.getpid(), 1)
    assert abs(time.time() - float(stamp)) < 5
    assert [p.name for p in tmp_path.iterdir()] == ["heartbeat"]  # no temporary


async def test_before_the_first_beat_the_file_is_kept_fresh_until_told(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """While the IOC waits for its PLC there is no scan to beat: the file is
    rewritten all the same, the count at 0, until the scan takes over."""
    monkeypatch.setattr(heartbeat_module, "WAITING_PERIOD_S", 0.01)
    path = tmp_path / "heartbeat"
    heartbeat = Heartbeat(path)
    written = path.read_text()
    heartbeat.keep_fresh()
    await asyncio.sleep(0.2)
    rewritten = path.read_text()
    heartbeat.stop_keeping_fresh()
    await asyncio.sleep(0)
    stopped = path.read_text()
    await asyncio.sleep(0.1)

    assert rewritten != written  # a newer time
    assert rewritten.split()[:2] == [str(os.getpid()), "0"]  # not a beat
    assert path.read_text() == stopped  # no longer rewritten
    assert [p.name for p in tmp_path.iterdir()] == ["heartbeat"]


def test_start_count_counts_in_its_folder(tmp_path: Path) -> None:
    assert [count_start(tmp_path), count_start(tmp_path)] == [1, 2]
    (tmp_path / "start-count").write_text("garbage")
    assert count_start(tmp_path) == 1
    assert count_start(tmp_path / "start-count") == 0  # not a folder: not kept
