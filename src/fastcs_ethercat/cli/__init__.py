"""The one command-line entry point, `fastcs-ethercat`, and its subcommands.

Each command lives in its own module; this module only assembles them, sets
up logging (`--log-level` here or on any command) and turns `UserError` into
a one-line message and a non-zero exit code. The command groups' modules are
imported only when their group is named (or listed by `--help`): the IOC's
start does not pay for the ESI parser, terminal generation and rich.
"""

from __future__ import annotations

import importlib
import logging
import sys
from typing import TYPE_CHECKING, Any, Final

import typer
from typer.core import TyperCommand, TyperGroup

from fastcs_ethercat import __version__, collector, stop_signals
from fastcs_ethercat.cli.bench import bench_command
from fastcs_ethercat.cli.ioc import demo_command
from fastcs_ethercat.cli.options import (
    DEFAULT_LOG_LEVEL,
    LogLevelOption,
    plain_typer,
)
from fastcs_ethercat.cli.sim import sim_command
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.logs import setup_logging

if TYPE_CHECKING:  # Typer vendors Click; its groups' methods take these types
    from typer._click import Command, Context

COMMAND_GROUPS: Final = {
    "init": ("fastcs_ethercat.cli.init", "init_app"),
    "terminals": ("fastcs_ethercat.cli.terminals", "terminals_app"),
    "ioc": ("fastcs_ethercat.cli.ioc", "ioc_app"),
    "chain": ("fastcs_ethercat.cli.chain", "chain_app"),
}
"""Command (group) name -> (module, Typer app); `--help` lists them in this
order, after the single commands. An app of one command and no callback is
that command (`init`), any other a group."""


class _NotImported(TyperCommand):
    """Stands in for a command group until it is asked for."""


class _LazyGroups(TyperGroup):
    """The root command: a group of `COMMAND_GROUPS` is imported when asked for
    (to run or for `--help`); a typo's suggestion needs only the names."""

    def __init__(self, *args: Any, **attrs: Any) -> None:
        super().__init__(*args, **attrs)
        for name in COMMAND_GROUPS:
            self.commands[name] = _NotImported(name)

    def get_command(self, ctx: Context, cmd_name: str) -> Command | None:
        if isinstance(self.commands.get(cmd_name), _NotImported):
            module, attribute = COMMAND_GROUPS[cmd_name]
            app: typer.Typer = getattr(importlib.import_module(module), attribute)
            self.commands[cmd_name] = typer.main.get_command(app)
        return super().get_command(ctx, cmd_name)


_typer_app = plain_typer(
    "Beckhoff EtherCAT terminals under TwinCAT as EPICS PVs.",
    no_args_is_help=True,
    cls=_LazyGroups,
)
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
    collector.release()  # held by the entry point; the IOC holds it again
    setup_logging(log_level or DEFAULT_LOG_LEVEL)


def run_cli(command: typer.Typer, prog_name: str | None = None) -> None:
    """Run a Typer app; a `UserError` becomes one line on stderr and its exit
    code; SIGTERM or SIGHUP at any moment a clean exit 0 (`stop_signals`)."""
    stop_signals.install()
    try:
        command(prog_name=prog_name)
    except UserError as error:
        typer.echo(f"error: {error}", err=True)
        sys.exit(error.exit_code)
    except stop_signals.Stopped as stopped:
        logging.getLogger(__name__).info("stopped by %s", stopped)
        sys.exit(0)


def app() -> None:
    """The `fastcs-ethercat` command line (`__main__.main` runs it)."""
    run_cli(_typer_app, "fastcs-ethercat")
