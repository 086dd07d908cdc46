"""The offline half: building the ESI catalog and regenerating `terminals/`."""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lxml import etree

from fastcs_ethercat.bench.context import BenchContext
from fastcs_ethercat.esi import build_catalog, parse_all
from fastcs_ethercat.esi.sources import find_documents

FULL_PARSE_RUNS = 3
"""Repeats of the plain and the full parse (each ~1 s): the median is kept."""


def esi_catalog_s(context: BenchContext) -> float:
    """Median seconds to parse every ESI file and build the catalog, cold
    (an empty cache in a temporary XDG_CACHE_HOME, never the user's)."""
    times = []
    saved = os.environ.get("XDG_CACHE_HOME")
    try:
        for _ in range(context.plan.runs):
            with tempfile.TemporaryDirectory(dir=context.scratch) as cache:
                os.environ["XDG_CACHE_HOME"] = cache
                start = time.perf_counter()
                build_catalog(context.esi)
                times.append(time.perf_counter() - start)
    finally:
        if saved is None:
            os.environ.pop("XDG_CACHE_HOME", None)
        else:
            os.environ["XDG_CACHE_HOME"] = saved
    return round(statistics.median(times), 3)


def terminals_regenerate_s(context: BenchContext) -> float:
    """Median seconds of `fastcs-ethercat terminals regenerate` on a copy of
    the terminal directory (the whole command, process start included)."""
    times = []
    for run in range(context.plan.runs):
        copy = context.scratch / f"regenerate-{run}" / "terminals"
        shutil.copytree(context.terminals, copy)
        command = [sys.executable, "-m", "fastcs_ethercat", "terminals", "regenerate"]
        command += [str(copy), "--esi", str(context.esi)]
        for extra in context.extra_esi:
            command += ["--esi", str(extra)]
        env = {**os.environ, "XDG_CACHE_HOME": str(copy.parent / "cache")}
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, env=env)
        times.append(time.perf_counter() - start)
        if done.returncode != 0:
            raise RuntimeError(f"terminals regenerate: {done.stderr.strip()[-500:]}")
        shutil.rmtree(copy.parent, ignore_errors=True)
    return round(statistics.median(times), 3)


def full_parse_cpu_s(source: Path, runs: int) -> tuple[float, float, int, int]:
    """Median CPU seconds (process time, so other load does not count) of a
    plain `lxml.etree.fromstring` of every ESI document under `source` and of
    `parse_all` of them, taken in turn so that a change of the machine's
    load touches both alike; with the document and device counts."""
    documents = find_documents(source)
    plain_s, full_s, devices = [], [], 0
    for _ in range(runs):
        start = time.process_time()
        for document in documents:
            etree.fromstring(document.read())
        plain_s.append(time.process_time() - start)
        start = time.process_time()
        devices = len(parse_all(source).devices)
        full_s.append(time.process_time() - start)
    plain, full = statistics.median(plain_s), statistics.median(full_s)
    return plain, full, len(documents), devices


def esi_full_parse(context: BenchContext) -> dict[str, float | int]:
    """Every device of the ESI source fully parsed (`parse_all`) against a
    plain `lxml.etree.fromstring` of the same documents, in this run: CPU
    seconds, medians."""
    plain, full, documents, devices = full_parse_cpu_s(context.esi, FULL_PARSE_RUNS)
    return {
        "documents": documents,
        "devices": devices,
        "plain_lxml_cpu_s": round(plain, 3),
        "full_parse_cpu_s": round(full, 3),
        "ratio": round(full / plain, 2),
    }


def default_extra_esi(repo: Path) -> tuple[Path, ...]:
    """ESI files the shared directory lacks but the terminal YAML needs."""
    fixture = repo / "tests" / "data" / "esi" / "EL3356-0010-fixture.xml"
    return (fixture,) if fixture.is_file() else ()


__all__ = [
    "default_extra_esi",
    "esi_catalog_s",
    "esi_full_parse",
    "full_parse_cpu_s",
    "terminals_regenerate_s",
]
