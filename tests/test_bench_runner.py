"""`fastcs-ethercat bench` end to end at the smallest sizes: every section
runs against a real simulator and IOC, and the JSON has the agreed shape.
No timing is asserted (figures are printed by the benchmark, not tested)."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fastcs_ethercat.bench import bytecode
from fastcs_ethercat.bench.chains import (
    SCAN_SYMBOLS_PER_TERMINAL,
    demo_mix,
    mixed_slaves,
    scan_slaves,
    terminals_with_coe,
)
from fastcs_ethercat.bench.context import BenchContext, BenchPlan
from fastcs_ethercat.bench.esi_sections import default_extra_esi, esi_full_parse
from fastcs_ethercat.bench.repeater import RUN_TOKEN, stop_repeaters_of_run
from fastcs_ethercat.bench.report import (
    REQUIRED_KEYS,
    fault_lines,
    scan_line,
    summary_lines,
    write_json,
)
from fastcs_ethercat.bench.runner import run_bench, server_ports
from fastcs_ethercat.cli import _typer_app
from tests.conftest import ESI_SUBSET, REPO_ROOT, SHARED_ESI, TERMINALS_DIR

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
TINY = BenchPlan(
    chain_sizes=(3,),
    scan_symbols=(SCAN_SYMBOLS_PER_TERMINAL,),
    latency_rates_hz=(20.0,),
    runs=1,
    window_s=0.3,
    latency_samples=3,
    start_timeout_s=60.0,
    coe_chain_sizes=(),
    deadband_symbols=SCAN_SYMBOLS_PER_TERMINAL,
)


def bench_context(scratch: Path) -> BenchContext:
    """The repository's inputs at the tiny sizes."""
    return BenchContext(
        terminals=TERMINALS_DIR,
        esi=SHARED_ESI,
        demo_chain=DEMO_CHAIN,
        scratch=scratch,
        plan=TINY,
        extra_esi=default_extra_esi(REPO_ROOT),
    )


@pytest.fixture(scope="module")
def document() -> dict[str, Any]:
    """One tiny run of the start and latency sections (scan: test_bench_scan)."""
    lines: list[str] = []
    return run_bench(bench_context, ("start", "latency"), progress=lines.append)


def is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


@pytest.mark.e2e
@pytest.mark.perf
def test_the_document_has_every_key(document: dict[str, Any]) -> None:
    assert set(REQUIRED_KEYS) <= document.keys()
    assert document["machine"]["cores"] >= 1
    assert document["machine"]["cpu_model"]
    assert document["esi_catalog_s"] == {"skipped": "section not selected"}
    assert document["esi_full_parse_ratio"] == {"skipped": "section not selected"}
    assert document["scan"] == []
    assert document["scan_deadband"] == {"skipped": "section not selected"}
    json.dumps(document)  # JSON-ready as it is


@pytest.mark.e2e
@pytest.mark.perf
def test_start_gives_seconds_and_memory_per_chain_size(
    document: dict[str, Any],
) -> None:
    assert is_number(document["ioc_start_s"]["3"]), document["ioc_start_s"]
    assert is_number(document["rss_mb"]["3"]), document["rss_mb"]
    detail = document["ioc_start_detail"][0]
    assert detail["terminals"] == 3 and detail["pvs"] > 0
    assert detail["ready_line_s"] <= detail["start_s"]


@pytest.mark.e2e
@pytest.mark.perf
def test_latency_has_median_and_p99(document: dict[str, Any]) -> None:
    figures = document["latency_ms"]["20"]
    assert "error" not in figures, figures
    assert 0 < figures["p50"] <= figures["p99"]
    assert figures["samples"] == TINY.latency_samples


@pytest.mark.e2e
@pytest.mark.perf
def test_the_summary_and_json_file(document: dict[str, Any], tmp_path: Path) -> None:
    lines = summary_lines(document)
    assert any(line.startswith("latency @20 Hz") for line in lines)
    path = tmp_path / "bench.json"
    write_json(document, path)
    assert json.loads(path.read_text()) == document


def test_chains_of_any_size_and_coe_selection(tmp_path: Path) -> None:
    mix = demo_mix(DEMO_CHAIN)
    assert [s["type"] for s in mixed_slaves(30, mix)[24:26]] == ["EK1100", "EL1014"]
    slaves = scan_slaves(1000, changing=True)
    terminals = [s for s in slaves if s["type"] == "EL3104"]
    assert len(terminals) * SCAN_SYMBOLS_PER_TERMINAL >= 1000
    assert terminals[0]["signal"]["kind"] == "counter"
    copy = terminals_with_coe(TERMINALS_DIR, tmp_path / "terminals")
    text = (copy / "EL3104.yaml").read_text()
    coe = text.split("\n  coe_objects:\n", 1)[1]
    assert "    selected: true\n" in coe and "    selected: false\n" not in coe


def test_the_cli_refuses_an_unknown_section() -> None:
    result = CliRunner().invoke(_typer_app, ["bench", "--only", "everything"])
    assert result.exit_code != 0
    assert "'everything' is not one of 'esi', 'start', 'scan', 'latency'" in (
        result.output
    )


def test_the_full_parse_is_timed_against_plain_lxml(tmp_path: Path) -> None:
    """On the ESI files the tests ship: the same documents, CPU seconds."""
    context = BenchContext(
        terminals=TERMINALS_DIR,
        esi=ESI_SUBSET,
        demo_chain=DEMO_CHAIN,
        scratch=tmp_path,
        plan=TINY,
    )
    figures = esi_full_parse(context)

    assert figures["documents"] >= 1 and figures["devices"] >= 1
    assert figures["plain_lxml_cpu_s"] > 0
    assert figures["full_parse_cpu_s"] > 0 and figures["ratio"] > 0


def test_the_bench_serves_on_ports_of_its_own() -> None:
    chosen = server_ports({})
    kept = server_ports({"EPICS_CA_SERVER_PORT": "5999"})

    assert sorted(chosen) == [
        "EPICS_CA_SERVER_PORT", "EPICS_PVA_BROADCAST_PORT", "EPICS_PVA_SERVER_PORT"
    ]  # fmt: skip
    assert "5064" not in chosen.values() and kept["EPICS_CA_SERVER_PORT"] == "5999"


def test_the_bench_compiles_the_package_bytecode_as_an_install_has_it() -> None:
    """An IOC start is timed against compiled modules, as pip installs them."""
    cached = Path(importlib.util.cache_from_source(bytecode.__file__))
    cached.unlink(missing_ok=True)

    assert bytecode.compile_package()
    assert cached.is_file()


def _scan_entry(symbols: int, cpu_changing_pct: float) -> dict[str, Any]:
    return {
        "symbols": symbols,
        "requests_per_cycle": 3.0,
        "cpu_unchanged_pct": 3.0,
        "cpu_changing_pct": cpu_changing_pct,
        "updates_per_s": symbols * 10.0,
    }


def test_each_scan_is_judged_by_its_own_target_only() -> None:
    """The 20 % CPU target is the ~1 000-symbol case's: the full run's ~5 000
    symbols at 50 % CPU is no missed target."""
    small, middle, big = (
        scan_line(_scan_entry(1184, 25.0)),
        scan_line(_scan_entry(5846, 50.0)),
        scan_line(_scan_entry(11684, 90.0)),
    )
    assert "25.0% changing with a monitoring  [target MISSED]" in small
    assert "[target" not in middle
    assert big.count("[target met]") == 3 and "MISSED" not in big


def test_fault_timings_are_judged_against_their_targets() -> None:
    lines = fault_lines(
        {
            "stall": {"loss_s": 0.7, "recovery_s": 6.2},
            "slave_preop": {"loss_s": 1.8, "recovery_s": 3.5},
            "link_lost": {"loss_s": 2.6, "recovery_s": 4.0},
            "pdo_change": {"loss_s": 1.9, "recovery_s": 0.8},
            "plc_appears": {"served_invalid": True, "live_s": 1.2},
        }
    )
    assert lines == [
        "fault stall: INVALID in 0.7 s  [target met],"
        " valid again in 6.2 s  [target MISSED]",
        "fault slave_preop: INVALID in 1.8 s  [target met],"
        " valid again in 3.5 s  [target MISSED]",
        "fault link_lost: INVALID in 2.6 s  [target MISSED],"
        " valid again in 4.0 s  [target met]",
        "fault pdo_change: INVALID in 1.9 s  [target met],"
        " valid again in 0.8 s  [target met]",
        "PLC appears after start: live in 1.2 s  [target met]",
    ]
    assert fault_lines({"error": "TimeoutError: no"}) == [
        "faults: ERROR TimeoutError: no"
    ]


@pytest.mark.e2e
def test_the_bench_stops_the_carepeaters_of_its_run_only(tmp_path: Path) -> None:
    """A caRepeater outlives the client that spawned it (its parent becomes
    init); the bench finds its own by the run's token in their environment."""
    stand_in = tmp_path / "caRepeater"  # a process named as the real one
    sleep = shutil.which("sleep")
    assert sleep is not None
    shutil.copy(sleep, stand_in)
    ours, theirs = (
        subprocess.Popen([stand_in, "60"], env={**os.environ, RUN_TOKEN: token})
        for token in ("ours", "theirs")
    )
    try:
        assert stop_repeaters_of_run("ours") == [ours.pid]
        assert ours.wait(timeout=5) != 0  # terminated
        assert theirs.poll() is None
    finally:
        for process in (ours, theirs):
            process.kill()
            process.wait()
