"""`python -m fastcs_ethercat.cli.sim_main`: the sim command alone (what
`SimProcess` starts), logging at warning unless told, with the same one-line
handling of user errors as the main CLI.

A module of its own: run as `-m`, `cli.sim` itself would be imported twice
(once by the `cli` package, once as `__main__`), which Python warns about.
"""

from __future__ import annotations

from fastcs_ethercat.cli import run_cli
from fastcs_ethercat.cli.options import plain_typer
from fastcs_ethercat.cli.sim import SIM_HELP, sim_command
from fastcs_ethercat.logs import LogLevel, setup_logging


def main() -> None:
    setup_logging(LogLevel.WARNING)
    app = plain_typer(SIM_HELP)
    app.command()(sim_command)
    run_cli(app, "fastcs-ethercat sim")


if __name__ == "__main__":
    main()
