"""`fastcs-ethercat bench`: benchmarks against the protocol's limits.

    fastcs-ethercat bench [--quick] [--json FILE] [--only SECTION ...]

Sections: esi (catalog, regenerate), start (IOC start and peak RSS per chain
size, with and without CoE), scan (requests per cycle, CPU, updates received),
latency (value change to CA monitor event). Everything on loopback, the
simulator and the IOC in their own processes. The terminal types and the
demo chain default to the shipped ones; the ESI source to the same as every
`terminals` command (`--esi`, else the zip `terminals update-cache` fetched).
"""

from __future__ import annotations

import json
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from fastcs_ethercat.cli.options import (
    LogLevelOption,
    TerminalsDirOption,
    apply_log_level,
    terminals_dir,
)
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.shipped import BUILTIN_TERMINALS_DIR, DEMO_CHAIN


class Section(StrEnum):
    """The benchmark sections (`bench.runner.SECTIONS`, which a test keeps
    equal), as `--only` choices; the runner itself loads only when run."""

    ESI = "esi"
    START = "start"
    SCAN = "scan"
    LATENCY = "latency"
    FAULTS = "faults"


SECTIONS = tuple(str(section) for section in Section)


def bench_command(
    quick: Annotated[
        bool, typer.Option("--quick", help="A reduced set, under 3 minutes.")
    ] = False,
    json_file: Annotated[
        Path | None,
        typer.Option("--json", metavar="FILE", help="Also write the figures here."),
    ] = None,
    only: Annotated[
        list[Section] | None,
        typer.Option(
            "--only",
            metavar=f"[{'|'.join(SECTIONS)}]",
            help="Run only this section (repeatable).",
        ),
    ] = None,
    terminals: TerminalsDirOption = BUILTIN_TERMINALS_DIR,
    esi: Annotated[
        Path | None,
        typer.Option(
            "--esi",
            metavar="SRC",
            help="ESI directory, XML file or Beckhoff_EtherCAT_XML.zip; "
            "default: the zip fetched by `terminals update-cache`.",
        ),
    ] = None,
    demo_chain: Annotated[
        Path,
        typer.Option(
            "--demo-chain",
            metavar="FILE",
            help="Chain whose mix start-up repeats (default: the demo's).",
            show_default=False,
        ),
    ] = DEMO_CHAIN,
    log_level: LogLevelOption = None,
) -> None:
    """Benchmarks: ESI, IOC start, scan cost, latency, memory (loopback).

    Measures and prints; with --json also writes the figures as JSON.
    """
    apply_log_level(log_level)
    from fastcs_ethercat.bench.context import FULL_PLAN, QUICK_PLAN, BenchContext
    from fastcs_ethercat.bench.esi_sections import default_extra_esi
    from fastcs_ethercat.bench.report import summary_lines, write_json
    from fastcs_ethercat.bench.runner import run_bench
    from fastcs_ethercat.terminals.esi_sources import esi_sources

    sections = tuple(str(section) for section in only) if only else SECTIONS
    terminals_dir(terminals)
    esi_source = esi_sources([esi] if esi else None)[0] if "esi" in sections else None
    if not demo_chain.is_file():
        raise UserError("not found; give a chain with --demo-chain", path=demo_chain)
    plan = QUICK_PLAN if quick else FULL_PLAN
    repo = terminals.resolve().parent

    def context_for(scratch: Path) -> BenchContext:
        return BenchContext(
            terminals=terminals.resolve(),
            esi=(esi_source or Path()).resolve(),
            demo_chain=demo_chain.resolve(),
            scratch=scratch,
            plan=plan,
            extra_esi=default_extra_esi(repo),
        )

    document = run_bench(context_for, sections, progress=_progress)
    for line in summary_lines(document):
        typer.echo(line)
    if json_file is not None:
        write_json(document, json_file)
        typer.echo(f"bench: figures written to {json_file}")
    else:
        typer.echo(json.dumps(document, indent=2))


def _progress(message: str) -> None:
    typer.echo(message, err=True)
