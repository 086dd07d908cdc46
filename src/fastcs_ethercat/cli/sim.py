"""`fastcs-ethercat sim`: run the TwinCAT simulator until SIGINT or SIGTERM.

Also runnable alone as `python -m fastcs_ethercat.cli.sim_main ...` (what
`SimProcess` starts).
"""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path
from typing import Annotated, Any

import typer

from fastcs_ethercat.ads.constants import ADS_TCP_PORT, ADS_UDP_PORT
from fastcs_ethercat.cli.options import (
    LogLevelOption,
    apply_log_level,
    terminals_dir,
)
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.loopback import LOOPBACK

log = logging.getLogger("fastcs_ethercat.sim")

SIM_HELP = "Run a simulated TwinCAT system with EtherCAT masters that speaks ADS."


def _port_option(flag: str, serves: str) -> Any:
    """A port option; 0 asks for any free port (what tests and benchmarks do)."""
    return typer.Option(flag, metavar="PORT", help=f"{serves} port (0 = free).")


def _check_port(value: int | None, option: str) -> None:
    if value is not None and not 0 <= value <= 0xFFFF:
        raise UserError(f"{option} must be 0..65535 (0 = any free port), got {value}")


def sim_command(
    chain: Annotated[
        Path,
        typer.Option(
            "--chain",
            metavar="FILE",
            help="Chain description (YAML): masters and their terminals.",
        ),
    ],
    terminals: Annotated[
        Path | None,
        typer.Option(
            "--terminals",
            metavar="DIR",
            help="Directory of terminal YAML (default: the chain file's "
            "`terminal_dirs`, else the shipped types).",
            show_default=False,
        ),
    ] = None,
    revisions: Annotated[
        list[Path] | None,
        typer.Option(
            "--revisions",
            metavar="DIR",
            help="Terminal YAML of other revisions (files or directories; "
            "repeatable): a slave whose chain entry gives such a revision is "
            "played from it.",
        ),
    ] = None,
    host: Annotated[
        str, typer.Option("--host", metavar="ADDRESS", help="Address to bind.")
    ] = LOOPBACK,
    port: Annotated[int, _port_option("--port", "AMS/TCP")] = ADS_TCP_PORT,
    udp_port: Annotated[
        int, _port_option("--udp-port", "UDP discovery and add-route")
    ] = ADS_UDP_PORT,
    control_port: Annotated[
        int | None, _port_option("--control-port", "HTTP JSON control API")
    ] = None,
    seed: Annotated[
        int, typer.Option("--seed", metavar="N", help="Seed of simulated signals.")
    ] = 0,
    cycle_ms: Annotated[
        float | None,
        typer.Option(
            "--cycle-ms", metavar="MS", help="Task cycle in ms (default: the chain's)."
        ),
    ] = None,
    cycle_per_poll: Annotated[
        bool,
        typer.Option(
            "--cycle-per-poll",
            help="Advance the task one cycle per client poll (the first request "
            "3/4 of a cycle after the last advance), not by the clock: a client "
            "polling once a cycle sees every value change at every poll "
            "(benchmarks).",
        ),
    ] = False,
    log_level: LogLevelOption = None,
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
    ports = {"--port": port, "--udp-port": udp_port, "--control-port": control_port}
    for option, value in ports.items():
        _check_port(value, option)
    if cycle_ms is not None and not cycle_ms > 0:
        raise UserError(f"--cycle-ms must be > 0, got {cycle_ms}")
    if not chain.is_file():
        raise UserError("chain file not found", path=chain)
    if terminals is not None:
        terminals_dir(terminals)
    apply_log_level(log_level)

    from fastcs_ethercat.chain.file import load_chain
    from fastcs_ethercat.sim.runner import SimulatorConfig, serve
    from fastcs_ethercat.twincat.resolve import load_revisions
    from fastcs_ethercat.twincat.target import SimTarget

    spec = load_chain(chain)
    if cycle_ms is not None:
        spec.system.task_cycle_ms = cycle_ms
    target = SimTarget.from_chain(
        spec,
        terminals,
        seed=seed,
        revisions=load_revisions(revisions) if revisions else None,
    )
    for note in target.notes:
        log.warning("%s", note)
    config = SimulatorConfig(
        host=host,
        port=port,
        udp_port=udp_port,
        control_port=control_port,
        cycle_per_poll=cycle_per_poll,
    )
    try:
        asyncio.run(serve(target, config, exit_with_stdin=exit_with_stdin))
    except OSError as error:
        raise UserError(f"cannot listen on {host}: {error.strerror or error}") from None
