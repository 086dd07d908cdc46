"""`fastcs-ethercat terminals`: ESI XML to terminal YAML."""

from __future__ import annotations

import typer

terminals_app = typer.Typer(
    help="Read Beckhoff ESI XML and generate or regenerate terminal YAML.",
    no_args_is_help=True,
)
