"""The one command-line entry point, `fastcs-ethercat`, and its subcommand groups.

Each group lives in its own module; this module only assembles them and turns
`UserError` into a one-line message and a non-zero exit code.
"""

from __future__ import annotations

import sys

import typer

from fastcs_ethercat import __version__
from fastcs_ethercat.cli.bench import bench_app
from fastcs_ethercat.cli.ioc import demo_command, ioc_command
from fastcs_ethercat.cli.sim import sim_app
from fastcs_ethercat.cli.terminals import terminals_app
from fastcs_ethercat.errors import UserError

_typer_app = typer.Typer(
    name="fastcs-ethercat",
    help="Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
_typer_app.add_typer(terminals_app, name="terminals")
_typer_app.add_typer(sim_app, name="sim")
_typer_app.add_typer(bench_app, name="bench")
_typer_app.command("ioc")(ioc_command)
_typer_app.command("demo")(demo_command)


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
) -> None:
    """Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs."""


def app() -> None:
    """Run the CLI; a `UserError` becomes one line on stderr and exit code 2."""
    try:
        _typer_app()
    except UserError as error:
        typer.echo(f"error: {error}", err=True)
        sys.exit(error.exit_code)
