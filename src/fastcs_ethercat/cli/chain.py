"""`fastcs-ethercat chain dump`: a live target's chain as a chain file.

    fastcs-ethercat chain dump --target HOST[:PORT] [--ams-net-id ID]
                               [--terminals DIR]... --out FILE
    fastcs-ethercat chain dump --config ioc.yaml --out FILE

The file is in the simulator's chain format: `sim --chain FILE` plays the
rack offline, and an IOC serves from it while its PLC does not answer
(`chain: FILE` in its configuration). Discovery is the IOC's own, with its
terminal YAML (to tell the PDO group each terminal runs); with `--config`
the target, NetId, route and terminal directories come from an IOC
configuration.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from fastcs_ethercat.cli.options import (
    AmsNetIdOption,
    LogLevelOption,
    TargetOption,
    apply_log_level,
    plain_typer,
)
from fastcs_ethercat.errors import UserError

chain_app = plain_typer("Read a live target's EtherCAT chain into a chain file.")


@chain_app.callback()
def chain_callback() -> None:
    """Read a live target's EtherCAT chain into a chain file."""


@chain_app.command("dump")
def dump_command(
    out: Annotated[
        Path,
        typer.Option("--out", metavar="FILE", help="Chain file to write (YAML)."),
    ],
    target: TargetOption = None,
    ams_net_id: AmsNetIdOption = None,
    terminals: Annotated[
        list[Path] | None,
        typer.Option(
            "--terminals",
            metavar="DIR",
            help="Terminal YAML (repeatable; default: the shipped types).",
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            metavar="FILE",
            help="Take target, NetId, route and terminal YAML from an IOC "
            "configuration (flags override it).",
        ),
    ] = None,
    log_level: LogLevelOption = None,
) -> None:
    """Discover the target and write its chain: masters, terminals in bus
    order with identities, PDO groups and oversampling factors."""
    apply_log_level(log_level)
    if config is None and target is None:
        raise UserError("give the target with --target HOST[:PORT] (or --config FILE)")
    import asyncio

    from fastcs_ethercat.ioc.boot import discover_once
    from fastcs_ethercat.ioc.chains import write_chain
    from fastcs_ethercat.ioc.config import load_ioc_config
    from fastcs_ethercat.terminals.loader import load_terminals

    overrides: dict[str, Any] = {
        "target": target,
        "ams_net_id": ams_net_id,
        "terminal_dirs": [str(path) for path in terminals] if terminals else None,
    }
    if config is None:
        overrides["prefix"] = "CHAIN"  # required by the config, unused here
    settings = load_ioc_config(config, overrides)
    registry = load_terminals(settings.terminal_dirs)
    plan = asyncio.run(discover_once(settings, registry))
    try:
        write_chain(plan, settings.target, out)
    except OSError as error:
        raise UserError(f"cannot write: {error.strerror or error}", path=out) from None
    terminals_found = sum(len(master.terminals) for master in plan.masters)
    typer.echo(
        f"wrote {out}: {len(plan.masters)} master(s), {terminals_found} terminals "
        f"of {settings.target}"
    )
