"""`fastcs-ethercat sim`: run the TwinCAT simulator until SIGINT or SIGTERM.

Also runnable as `python -m fastcs_ethercat.cli.sim ...` (what `SimProcess`
starts), with the same one-line handling of user errors as the main CLI.
"""

from __future__ import annotations

import asyncio
import logging
import sys
from pathlib import Path
from typing import Annotated

import typer

from fastcs_ethercat.ads.constants import ADS_TCP_PORT, ADS_UDP_PORT
from fastcs_ethercat.errors import UserError

sim_app = typer.Typer(
    help="Run a simulated TwinCAT system with EtherCAT masters that speaks ADS.",
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _check_port(value: int | None, option: str) -> None:
    if value is not None and not 0 <= value <= 0xFFFF:
        raise UserError(f"{option} must be 0..65535 (0 = any free port), got {value}")


def default_terminals_dir(chain: Path) -> Path:
    """`terminals/` in the working directory, else beside the chain file or one
    level up (a chain in `ioc/` of a checkout finds the checkout's)."""
    candidates = [
        Path("terminals"),
        chain.parent / "terminals",
        chain.parent.parent / "terminals",
    ]
    for candidate in candidates:
        if candidate.is_dir():
            return candidate
    raise UserError(
        "no terminals directory found (looked in ./terminals and beside the "
        "chain file); give one with --terminals",
        path=chain,
    )


@sim_app.callback(invoke_without_command=True)
def sim(
    chain: Annotated[
        Path,
        typer.Option(
            "--chain", help="Chain description (YAML): masters and their terminals."
        ),
    ],
    terminals: Annotated[
        Path | None, typer.Option("--terminals", help="Directory of terminal YAML.")
    ] = None,
    host: Annotated[str, typer.Option("--host", help="Address to bind.")] = (
        "127.0.0.1"
    ),
    port: Annotated[
        int, typer.Option("--port", help="AMS/TCP port (0 = any free port).")
    ] = ADS_TCP_PORT,
    udp_port: Annotated[
        int, typer.Option("--udp-port", help="UDP discovery/add-route port (0 = free).")
    ] = ADS_UDP_PORT,
    control_port: Annotated[
        int | None,
        typer.Option("--control-port", help="HTTP JSON control API port (0 = free)."),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of simulated signals.")] = 0,
    cycle_ms: Annotated[
        float | None,
        typer.Option("--cycle-ms", help="Task cycle in ms (default: the chain's)."),
    ] = None,
    log_level: Annotated[
        str, typer.Option("--log-level", help="Python log level (stderr).")
    ] = "WARNING",
    exit_with_stdin: Annotated[
        bool,
        typer.Option(
            "--exit-with-stdin",
            hidden=True,
            help="Also stop when stdin closes (the parent process is gone).",
        ),
    ] = False,
) -> None:
    """Serve a simulated TwinCAT system over ADS (prints one line when ready)."""
    for value, option in ((port, "--port"), (udp_port, "--udp-port")):
        _check_port(value, option)
    _check_port(control_port, "--control-port")
    if cycle_ms is not None and not cycle_ms > 0:
        raise UserError(f"--cycle-ms must be > 0, got {cycle_ms}")
    if not chain.is_file():
        raise UserError("chain file not found", path=chain)
    if terminals is None:
        terminals = default_terminals_dir(chain)
    elif not terminals.is_dir():
        raise UserError("terminals directory not found", path=terminals)
    logging.basicConfig(
        level=log_level.upper(),
        stream=sys.stderr,
        format="%(asctime)s sim %(levelname)s %(name)s: %(message)s",
    )

    from fastcs_ethercat.sim.chain import load_chain
    from fastcs_ethercat.sim.runner import SimulatorConfig, serve
    from fastcs_ethercat.sim.target import SimTarget

    target = SimTarget.from_chain(load_chain(chain), terminals, seed=seed)
    config = SimulatorConfig(
        host=host,
        port=port,
        udp_port=udp_port,
        control_port=control_port,
        cycle_seconds=None if cycle_ms is None else cycle_ms / 1000,
    )
    try:
        asyncio.run(serve(target, config, exit_with_stdin=exit_with_stdin))
    except OSError as error:
        raise UserError(f"cannot listen on {host}: {error.strerror or error}") from None


def main() -> None:
    """Entry point for `python -m fastcs_ethercat.cli.sim`."""
    try:
        sim_app(prog_name="fastcs-ethercat sim")
    except UserError as error:
        typer.echo(f"error: {error}", err=True)
        sys.exit(error.exit_code)


if __name__ == "__main__":
    main()
