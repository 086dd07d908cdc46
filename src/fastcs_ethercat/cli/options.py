"""What several commands share: `--log-level`, the target, the terminal YAML
directory, and plain help.

Help is Click's plain format (`rich_markup_mode=None`): Typer's rich panels
print a type such as `<bool>` after every flag, which reads as if the flag
took a value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Final

import typer

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.logs import LogLevel, setup_logging

LogLevelOption = Annotated[
    LogLevel | None,
    typer.Option(
        "--log-level",
        case_sensitive=False,
        metavar="[debug|info|warning|error|critical]",
        help="Log level of this command's log lines (stderr). Default: info.",
    ),
]
DEFAULT_LOG_LEVEL: Final = LogLevel.INFO
TargetOption = Annotated[
    str | None,
    typer.Option(
        "--target", metavar="HOST[:PORT]", help="TwinCAT host[:ADS TCP port]."
    ),
]
AmsNetIdOption = Annotated[
    str | None,
    typer.Option(
        "--ams-net-id",
        metavar="ID",
        help="AMS NetId of the target (default: asked over UDP 48899).",
    ),
]

TerminalsDirOption = Annotated[
    Path,
    typer.Option(
        "--terminals",
        metavar="DIR",
        help="Directory of terminal YAML (default: the shipped types).",
        show_default=False,
    ),
]


def terminals_dir(path: Path) -> Path:
    """`--terminals` checked: a directory, else one line naming it."""
    if not path.is_dir():
        raise UserError("not a directory; give one with --terminals", path=path)
    return path


def apply_log_level(level: LogLevel | None) -> None:
    """Set up logging at `level` (the root's `--log-level` stays if None)."""
    if level is not None:
        setup_logging(level)


def plain_typer(help_text: str, **settings: Any) -> typer.Typer:
    """A Typer app with plain help and no completion or rich tracebacks."""
    return typer.Typer(
        help=help_text,
        rich_markup_mode=None,
        pretty_exceptions_enable=False,
        add_completion=False,
        **settings,
    )
