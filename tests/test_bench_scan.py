"""The scan section at its smallest (one EL3104, 36 symbols): requests per
poll cycle from the simulator's counters, CPU of the IOC unchanged and
changing (with and without a client monitoring), monitor updates received,
the deadband's effect. Shape only, no timing asserted."""

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
    assert is_number(entry["cpu_changing_no_client_pct"])


def test_the_client_is_camonitor_and_counts_what_the_ioc_posts(
    document: dict[str, Any],
) -> None:
    """The tools extra is installed with dev: the C client, whose received
    updates the IOC's own PostRate accounts for."""
    (entry,) = document["scan"]
    assert entry["client"] == "camonitor"
    assert entry["updates_posted_per_s"] > 0
    assert is_number(entry["client_cpu_pct"]) and is_number(entry["updates_lost_per_s"])


def test_the_deadband_run_reports_both_sides(document: dict[str, Any]) -> None:
    figures = document["scan_deadband"]
    assert "error" not in figures, figures
    for side in ("without", "with"):
        assert is_number(figures[f"updates_per_s_{side}"])
        assert is_number(figures[f"cpu_{side}"])
    assert figures["deadband"] > 2 * figures["noise_counts"]


def test_other_sections_are_marked_skipped(document: dict[str, Any]) -> None:
    assert document["latency_ms"] == {"skipped": "section not selected"}
    assert document["ioc_start_s"] == {"skipped": "section not selected"}
