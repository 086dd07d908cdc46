"""ESI parser speed: plain lxml, catalog (cold and cached), full parse.

Usage: python benchmarks/bench_esi.py [ESI_DIR] [--runs N]

Prints the median of N runs (default 5) of:
- plain `lxml.etree.parse` of every *.xml under ESI_DIR (the yardstick),
- `build_catalog` with an empty cache (every device parsed once, so the
  catalog knows which do not parse; once per ESI file),
- `build_catalog` answered from the cache (target: < 0.1 s),
- `parse_all`: every device fully parsed, in wall time and, like
  `fastcs-ethercat bench`'s `esi_full_parse_ratio`, in CPU time against a
  plain `lxml.etree.fromstring` of the same bytes in the same run (target:
  at most 1.5x),
- `fastcs-ethercat terminals regenerate` of a copy of `terminals/` (the whole
  command, process start included).
The cache lives in a temporary XDG_CACHE_HOME, never the user's.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from lxml import etree

from fastcs_ethercat.bench.esi_sections import full_parse_cpu_s
from fastcs_ethercat.esi import build_catalog, parse_all

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_ESI = REPO_ROOT / ".." / "shared" / "esi"
EL3356_FIXTURE = REPO_ROOT / "tests" / "data" / "esi" / "EL3356-0010-fixture.xml"


def median_seconds(action: Callable[[], object], runs: int) -> float:
    """Median wall time of `runs` calls of `action`."""
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def regenerate_copy(esi_dir: Path, scratch: Path) -> None:
    """Regenerate a copy of terminals/ through the real CLI."""
    copy = scratch / "terminals"
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(REPO_ROOT / "terminals", copy)
    command = [sys.executable, "-m", "fastcs_ethercat", "terminals", "regenerate"]
    command += [str(copy), "--esi", str(esi_dir), "--esi", str(EL3356_FIXTURE)]
    subprocess.run(command, check=True, capture_output=True)


def main() -> None:
    parser = argparse.ArgumentParser(description="ESI parser benchmark")
    parser.add_argument("esi_dir", nargs="?", type=Path, default=DEFAULT_ESI)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    files = sorted(args.esi_dir.rglob("*.xml"))
    size = sum(path.stat().st_size for path in files)
    print(f"{len(files)} files, {size / 1e6:.1f} MB under {args.esi_dir}")

    with tempfile.TemporaryDirectory() as cache_home:
        os.environ["XDG_CACHE_HOME"] = cache_home
        cache_dir = Path(cache_home) / "fastcs-ethercat" / "esi-catalog"

        def plain() -> None:
            for path in files:
                etree.parse(str(path))

        def cold() -> None:
            for stale in cache_dir.glob("*.json"):
                stale.unlink()
            build_catalog(args.esi_dir)

        plain_s = median_seconds(plain, args.runs)
        cold_s = median_seconds(cold, args.runs)
        nocache_s = median_seconds(
            lambda: build_catalog(args.esi_dir, use_cache=False), args.runs
        )
        build_catalog(args.esi_dir)
        warm_s = median_seconds(lambda: build_catalog(args.esi_dir), args.runs)
        devices = len(build_catalog(args.esi_dir))
        full_s = median_seconds(lambda: parse_all(args.esi_dir), max(1, args.runs))
        plain_cpu_s, full_cpu_s, _, _ = full_parse_cpu_s(args.esi_dir, args.runs)
        regenerate_s = median_seconds(
            lambda: regenerate_copy(args.esi_dir, Path(cache_home)), args.runs
        )

    print(f"plain lxml.etree.parse, all files : {plain_s:7.3f} s")
    ratio = cold_s / plain_s
    print(f"catalog, cold cache               : {cold_s:7.3f} s  ({ratio:.2f}x lxml)")
    print(f"catalog, no cache                 : {nocache_s:7.3f} s")
    print(f"catalog, cached                   : {warm_s:7.3f} s")
    print(f"full parse of {devices} devices      : {full_s:7.3f} s")
    cpu_ratio = full_cpu_s / plain_cpu_s
    print(
        f"  in CPU time                     : {full_cpu_s:7.3f} s  "
        f"({cpu_ratio:.2f}x plain lxml, {plain_cpu_s:.3f} s)"
    )
    print(f"terminals regenerate (20 files)   : {regenerate_s:7.3f} s")
    print(f"(medians of {args.runs} runs)")


if __name__ == "__main__":
    main()
