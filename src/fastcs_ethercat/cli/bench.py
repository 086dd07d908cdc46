"""`fastcs-ethercat bench`: benchmarks against the protocol's limits.

    fastcs-ethercat bench [--quick] [--json FILE] [--only SECTION ...]

Sections: esi (catalog, regenerate), start (IOC start and peak RSS per chain
size, with and without CoE), scan (requests per cycle, CPU, updates received),
latency (value change to CA monitor event). Everything on loopback, the
simulator and the IOC in their own processes. Run from a checkout: it needs
`terminals/`, `ioc/demo-chain.yaml` and the ESI files in `../shared/esi`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from fastcs_ethercat.errors import UserError

bench_app = typer.Typer(
    help="Benchmarks: ESI, IOC start, scan cost, latency, memory (loopback).",
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _need_dir(path: Path, option: str) -> Path:
    if not path.is_dir():
        raise UserError(f"not a directory; give one with {option}", path=path)
    return path


@bench_app.callback(invoke_without_command=True)
def bench(
    quick: Annotated[
        bool, typer.Option("--quick", help="A reduced set, under 3 minutes.")
    ] = False,
    json_file: Annotated[
        Path | None, typer.Option("--json", help="Also write the figures here.")
    ] = None,
    only: Annotated[
        list[str] | None,
        typer.Option("--only", help="Run only this section (repeatable)."),
    ] = None,
    terminals: Annotated[
        Path, typer.Option("--terminals", help="Directory of terminal YAML.")
    ] = Path("terminals"),
    esi: Annotated[
        Path, typer.Option("--esi", help="Directory of Beckhoff ESI files.")
    ] = Path("..") / "shared" / "esi",
    demo_chain: Annotated[
        Path, typer.Option("--demo-chain", help="Chain whose mix start-up repeats.")
    ] = Path("ioc") / "demo-chain.yaml",
) -> None:
    """Measure and print; with --json also write the figures as JSON."""
    from fastcs_ethercat.bench.context import FULL_PLAN, QUICK_PLAN, BenchContext
    from fastcs_ethercat.bench.esi_sections import default_extra_esi
    from fastcs_ethercat.bench.report import summary_lines, write_json
    from fastcs_ethercat.bench.runner import SECTIONS, run_bench

    sections = tuple(only or SECTIONS)
    unknown = sorted(set(sections) - set(SECTIONS))
    if unknown:
        raise UserError(
            f"unknown section {', '.join(unknown)}; choose from {', '.join(SECTIONS)}",
            where="--only",
        )
    _need_dir(terminals, "--terminals")
    if "esi" in sections:
        _need_dir(esi, "--esi")
    if not demo_chain.is_file():
        raise UserError("not found; give a chain with --demo-chain", path=demo_chain)
    plan = QUICK_PLAN if quick else FULL_PLAN
    repo = terminals.resolve().parent

    def context_for(scratch: Path) -> BenchContext:
        return BenchContext(
            terminals=terminals.resolve(),
            esi=esi.resolve(),
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
