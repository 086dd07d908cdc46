"""`fastcs-ethercat init`: a rack's IOC folder from the rack itself.

    fastcs-ethercat init --target HOST[:PORT] [--ams-net-id ID]
                         [--route-user U --password-env VAR]
                         --prefix PREFIX --esi SRC [--esi SRC ...] --out DIR
    fastcs-ethercat init --from-chain FILE --target HOST ...   (offline)
    fastcs-ethercat init ... --check      (report only; exit 1 if DIR differs)

This module is imported only when `init` is named (`cli.COMMAND_GROUPS`),
the work (`fastcs_ethercat.commission`) only when it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from fastcs_ethercat.cli.options import (
    AmsNetIdOption,
    LogLevelOption,
    apply_log_level,
    plain_typer,
)

init_app = plain_typer("Write a rack's IOC folder from the rack itself.")


@init_app.command("init")
def init_command(
    target: Annotated[
        str,
        typer.Option(
            "--target",
            metavar="HOST[:PORT]",
            help="TwinCAT host[:ADS TCP port] (with --from-chain: only written "
            "to ioc.yaml).",
        ),
    ],
    prefix: Annotated[
        str, typer.Option("--prefix", metavar="PREFIX", help="PV prefix of the IOC.")
    ],
    esi: Annotated[
        list[Path],
        typer.Option(
            "--esi",
            metavar="SRC",
            help="ESI directory, XML file or Beckhoff_EtherCAT_XML.zip "
            "(repeatable): for the types and revisions no YAML describes.",
        ),
    ],
    out: Annotated[
        Path,
        typer.Option("--out", metavar="DIR", help="The IOC folder to write."),
    ],
    ams_net_id: AmsNetIdOption = None,
    route_user: Annotated[
        str | None,
        typer.Option(
            "--route-user",
            metavar="USER",
            help="Add a route on the target as USER (with --password-env).",
        ),
    ] = None,
    password_env: Annotated[
        str | None,
        typer.Option(
            "--password-env",
            metavar="VAR",
            help="Environment variable holding the route password.",
        ),
    ] = None,
    from_chain: Annotated[
        Path | None,
        typer.Option(
            "--from-chain",
            metavar="FILE",
            help="Read the rack from a chain file (`chain dump`), not the target.",
        ),
    ] = None,
    check: Annotated[
        bool,
        typer.Option(
            "--check",
            help="Only report: exit 1 when the rack or DIR's files would change.",
        ),
    ] = False,
    log_level: LogLevelOption = None,
) -> None:
    """Discover the rack and write DIR: ioc.yaml, chain.yaml, terminal YAML,
    screens, PV lists and a services-repo instance; again on an existing DIR,
    update what changed on the rack and keep your edits."""
    apply_log_level(log_level)
    from fastcs_ethercat.commission.layout import Settings
    from fastcs_ethercat.commission.run import InitRequest, run_init
    from fastcs_ethercat.commission.summary import summary_lines

    request = InitRequest(
        settings=Settings(
            prefix=prefix,
            target=target,
            ams_net_id=ams_net_id,
            route_user=route_user,
            password_env=password_env,
        ),
        esi=tuple(esi),
        out=out,
        from_chain=from_chain,
        check=check,
    )
    outcome = run_init(request, lambda line: typer.echo(f"init: {line}", err=True))
    for line in summary_lines(outcome, out, check):
        typer.echo(line)
    if check and (outcome.changes or outcome.differences):
        raise typer.Exit(1)
