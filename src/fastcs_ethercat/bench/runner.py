"""Run the selected sections, never letting one failure stop the others.

A section that fails leaves `{"error": "..."}` where its figures would be,
so the JSON always has every key.
"""

from __future__ import annotations

import asyncio
import os
import re
import tempfile
import traceback
from collections.abc import Awaitable, Callable, Collection, Mapping
from pathlib import Path
from typing import Any, Final, TypeVar

from fastcs_ethercat.bench import (
    esi_sections,
    fault_section,
    ioc_sections,
    scan_section,
)
from fastcs_ethercat.bench.bytecode import compile_package
from fastcs_ethercat.bench.context import BenchContext
from fastcs_ethercat.bench.machine import describe_machine
from fastcs_ethercat.bench.repeater import mark_run, stop_repeaters_of_run
from fastcs_ethercat.bench.report import SCAN_KEYS
from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV
from fastcs_ethercat.process import free_port

SECTIONS: Final = ("esi", "start", "scan", "latency", "faults")
SKIPPED: Final = {"skipped": "section not selected"}
_T = TypeVar("_T")
Progress = Callable[[str], object]


_CAUSE = re.compile(r"^\w*(Error|Exception|Expired)\b.*")


def _error(error: BaseException) -> dict[str, str]:
    """One line: the error, and the last line of its text that names a cause
    (an IOC's log tail ends with its traceback's last line, not noise)."""
    lines = [line.strip() for line in str(error).strip().splitlines()]
    causes = [line for line in lines if _CAUSE.match(line)]
    detail = causes[-1] if causes else (lines[0] if lines else "")
    return {"error": f"{type(error).__name__}: {detail}"[:400]}


async def _guarded(
    action: Callable[[], Awaitable[_T]], progress: Progress, what: str
) -> _T | dict[str, str]:
    progress(f"bench: {what} ...")
    try:
        return await action()
    except Exception as error:  # a failed section is a figure too
        progress(f"bench: {what} failed:\n{traceback.format_exc(limit=3)}")
        return _error(error)


async def _in_thread(action: Callable[[], _T]) -> _T:
    return await asyncio.to_thread(action)


async def run_sections(
    context: BenchContext,
    sections: Collection[str] = SECTIONS,
    progress: Progress = print,
) -> dict[str, Any]:
    """Every figure of the selected sections as one JSON-ready document."""
    document: dict[str, Any] = {
        "quick": context.plan.runs == 1,
        "esi_catalog_s": SKIPPED,
        "esi_full_parse_ratio": SKIPPED,
        "esi_full_parse": SKIPPED,
        "terminals_regenerate_s": SKIPPED,
        "ioc_start_s": SKIPPED,
        "ioc_start_coe_s": SKIPPED,
        "ioc_start_detail": [],
        "scan": [],
        "scan_deadband": SKIPPED,
        "latency_ms": SKIPPED,
        "rss_mb": SKIPPED,
        "faults": SKIPPED,
        "machine": describe_machine(),
    }
    if "esi" in sections:
        document["esi_catalog_s"] = await _guarded(
            lambda: _in_thread(lambda: esi_sections.esi_catalog_s(context)),
            progress,
            "ESI catalog",
        )
        full_parse = await _guarded(
            lambda: _in_thread(lambda: esi_sections.esi_full_parse(context)),
            progress,
            "ESI full parse against plain lxml",
        )
        document["esi_full_parse"] = full_parse
        document["esi_full_parse_ratio"] = full_parse.get("ratio", full_parse)
        document["terminals_regenerate_s"] = await _guarded(
            lambda: _in_thread(lambda: esi_sections.terminals_regenerate_s(context)),
            progress,
            "terminals regenerate",
        )
    if "start" in sections:
        await _start_section(context, document, progress)
    if "scan" in sections:
        for symbols in context.plan.scan_symbols:
            entry = await _guarded(
                lambda s=symbols: scan_section.scan(context, s),
                progress,
                f"scan of ~{symbols} symbols",
            )
            if "error" in entry:
                entry = {
                    "target_symbols": symbols,
                    **dict.fromkeys(SCAN_KEYS),
                    **entry,
                }
            document["scan"].append(entry)
        document["scan_deadband"] = await _guarded(
            lambda: scan_section.deadband_effect(
                context, context.plan.deadband_symbols
            ),
            progress,
            f"deadband on ~{context.plan.deadband_symbols} noisy symbols",
        )
    if "latency" in sections:
        latency: dict[str, Any] = {}
        for rate in context.plan.latency_rates_hz:
            latency[f"{rate:g}"] = await _guarded(
                lambda r=rate: ioc_sections.latency(context, r),
                progress,
                f"latency at {rate:g} Hz",
            )
        document["latency_ms"] = latency
    if "faults" in sections:
        document["faults"] = await _guarded(
            lambda: fault_section.fault_timings(context),
            progress,
            "fault loss and recovery, PLC appearing",
        )
    return document


async def _start_section(
    context: BenchContext, document: dict[str, Any], progress: Progress
) -> None:
    starts: dict[str, Any] = {}
    starts_coe: dict[str, Any] = {}
    rss: dict[str, Any] = {}
    for size, coe in context.plan.starts():
        figures = await _guarded(
            lambda s=size, c=coe: ioc_sections.ioc_start(context, s, c),
            progress,
            f"IOC start, {size} terminals{' with CoE' if coe else ''}",
        )
        document["ioc_start_detail"].append({"terminals": size, "coe": coe, **figures})
        error = figures if "error" in figures else None
        if coe:
            starts_coe[str(size)] = error or figures["start_s"]
        else:
            starts[str(size)] = error or figures["start_s"]
            rss[str(size)] = error or figures["rss_mb"]
    document["ioc_start_s"] = starts
    document["ioc_start_coe_s"] = starts_coe or SKIPPED
    document["rss_mb"] = rss


def server_ports(environ: Mapping[str, str]) -> dict[str, str]:
    """CA and PVA ports of this run's own (those `environ` gives are kept):
    the IOCs it starts, one at a time, serve there and its clients look
    there, never at another IOC on the host's default ports."""
    wanted = {"EPICS_CA_SERVER_PORT": (True, True)}
    wanted["EPICS_PVA_SERVER_PORT"] = (True, False)
    wanted["EPICS_PVA_BROADCAST_PORT"] = (False, True)
    return {
        name: environ.get(name) or str(free_port(tcp=tcp, udp=udp))
        for name, (tcp, udp) in wanted.items()
    }


def run_bench(
    context_for: Callable[[Path], BenchContext],
    sections: Collection[str] = SECTIONS,
    progress: Progress = print,
) -> dict[str, Any]:
    """Run in a fresh scratch directory and loopback-only EPICS environment,
    the package's bytecode compiled as an install has it; stop any
    caRepeater the CA client library started."""
    compile_package()
    token = mark_run()
    for variable, value in EPICS_LOOPBACK_ENV.items():
        os.environ[variable] = value
    os.environ.update(server_ports(os.environ))
    with tempfile.TemporaryDirectory(prefix="fastcs-ethercat-bench-") as scratch:
        context = context_for(Path(scratch))
        try:
            return asyncio.run(run_sections(context, sections, progress))
        finally:
            stop_repeaters_of_run(token)
