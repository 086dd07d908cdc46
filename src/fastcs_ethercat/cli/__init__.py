"""The one command-line entry point, `fastcs-ethercat`, and its subcommands.

Each command lives in its own module; this module only assembles them, sets
up logging (`--log-level` here or on any command) and turns `UserError` into
a one-line message and a non-zero exit code.
"""

from __future__ import annotations

import sys

import typer

from fastcs_ethercat import __version__
from fastcs_ethercat.cli.bench import bench_command
from fastcs_ethercat.cli.chain import chain_app
from fastcs_ethercat.cli.ioc import demo_command, ioc_app
from fastcs_ethercat.cli.options import (
    DEFAULT_LOG_LEVEL,
    LogLevelOption,
    plain_typer,
)
from fastcs_ethercat.cli.sim import sim_command
from fastcs_ethercat.cli.terminals import terminals_app
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.logs import setup_logging

_typer_app = plain_typer(
    "Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs.", no_args_is_help=True
)
_typer_app.add_typer(terminals_app, name="terminals")
_typer_app.add_typer(ioc_app, name="ioc")
_typer_app.add_typer(chain_app, name="chain")
_typer_app.command("demo")(demo_command)
_typer_app.command("sim")(sim_command)
_typer_app.command("bench")(bench_command)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"fastcs-ethercat {__version__}")
        raise typer.Exit()


@_typer_app.callback()
def _main(
    version: bool = typer.Option(
        False,
        "--version",
        callback=_version_callback,
        is_eager=True,
        help="Print the version and exit.",
    ),
    log_level: LogLevelOption = None,
) -> None:
    """Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs."""
    setup_logging(log_level or DEFAULT_LOG_LEVEL)


def run_cli(command: typer.Typer, prog_name: str | None = None) -> None:
    """Run a Typer app; a `UserError` becomes one line on stderr and its exit code."""
    try:
        command(prog_name=prog_name)
    except UserError as error:
        typer.echo(f"error: {error}", err=True)
        sys.exit(error.exit_code)


def app() -> None:
    """The `fastcs-ethercat` entry point."""
    run_cli(_typer_app, "fastcs-ethercat")
