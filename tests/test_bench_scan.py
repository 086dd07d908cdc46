"""The scan section at its smallest (one EL3104, 36 symbols): requests per
poll cycle from the simulator's counters, CPU of the IOC unchanged and
changing, monitor updates received. Shape only, no timing asserted."""

from __future__ import annotations

from typing import Any

import pytest

from fastcs_ethercat.bench.chains import SCAN_SYMBOLS_PER_TERMINAL
from fastcs_ethercat.bench.report import SCAN_KEYS
from fastcs_ethercat.bench.runner import run_bench
from tests.test_bench_runner import bench_context, is_number

pytestmark = [pytest.mark.e2e, pytest.mark.perf]


@pytest.fixture(scope="module")
def document() -> dict[str, Any]:
    lines: list[str] = []
    return run_bench(bench_context, ("scan",), progress=lines.append)


def test_scan_counts_requests_cpu_and_updates(document: dict[str, Any]) -> None:
    (entry,) = document["scan"]
    assert "error" not in entry, entry
    assert all(is_number(entry[key]) for key in SCAN_KEYS), entry
    assert entry["symbols"] >= SCAN_SYMBOLS_PER_TERMINAL
    assert entry["requests_per_cycle"] > 0
    assert entry["updates_per_s"] > 0
    assert entry["updates_per_s_ideal"] == entry["symbols"] * entry["poll_rate_hz"]


def test_other_sections_are_marked_skipped(document: dict[str, Any]) -> None:
    assert document["latency_ms"] == {"skipped": "section not selected"}
    assert document["ioc_start_s"] == {"skipped": "section not selected"}
