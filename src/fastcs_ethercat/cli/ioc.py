"""`fastcs-ethercat ioc` (serve a TwinCAT target), `ioc schema`, and `demo`.

    fastcs-ethercat ioc --config ioc/bl01.yaml [--prefix P] [--target HOST[:PORT]]
                        [--ams-net-id ID] [--poll-rate HZ] [--read-only]
                        [--acf FILE] [--chain FILE]
                        [--list-pvs [--format text|archiver|autosave]]
                        [--log-level LEVEL] [--graylog-endpoint HOST:PORT
                        [--graylog-static-fields K:V,...]
                        [--graylog-env-fields K:ENV,...]]
    fastcs-ethercat ioc schema
    fastcs-ethercat demo [--prefix P] [--log-level LEVEL]

Flags override the file. `--list-pvs` connects, discovers, prints every PV
(`NAME ACCESS TYPE SOURCE`, one a line, sorted; or the Archiver Appliance
list, or the autosave request) and exits; with a chain file (`--chain` or
the config's `chain:`) it lists that chain without contacting the target.
Warnings go to stderr as log lines.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import Annotated

import typer

from fastcs_ethercat.cli.options import (
    AmsNetIdOption,
    LogLevelOption,
    TargetOption,
    apply_log_level,
    plain_typer,
)
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.pvlists import PvListFormat, pv_list_text
from fastcs_ethercat.logs import log_at_most
from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV
from fastcs_ethercat.shipped import DEMO_CHAIN, DEMO_CONFIG

log = logging.getLogger(__name__)
PYDANTIC_PLUGINS = ("PYDANTIC_DISABLE_PLUGINS", "__all__")
"""Pydantic's own switch, set for the IOC unless already set (an empty value
keeps every plugin): loading plugins reads the entry points of every
installed distribution (10-25 ms of a start), and the IOC validates only its
configuration, once."""
WARNINGS_SHOWN = 20
"""Warnings `--list-pvs` logs before it says how many more (all at debug)."""

ioc_app = plain_typer(
    "Serve every terminal of a TwinCAT target as EPICS PVs (CA and PVA).",
)


@ioc_app.callback(invoke_without_command=True)
def ioc_command(
    context: typer.Context,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config", metavar="FILE", help="IOC instance configuration (YAML)."
        ),
    ] = None,
    prefix: Annotated[
        str | None,
        typer.Option("--prefix", metavar="P", help="PV prefix (overrides the file)."),
    ] = None,
    target: TargetOption = None,
    ams_net_id: AmsNetIdOption = None,
    poll_rate: Annotated[
        float | None, typer.Option("--poll-rate", metavar="HZ", help="Poll rate.")
    ] = None,
    read_only: Annotated[
        bool, typer.Option("--read-only", help="Serve every output read-only.")
    ] = False,
    acf: Annotated[
        Path | None,
        typer.Option(
            "--acf", metavar="FILE", help="EPICS access security file (CA writes)."
        ),
    ] = None,
    chain: Annotated[
        Path | None,
        typer.Option(
            "--chain",
            metavar="FILE",
            help="Chain file (`chain dump`, the simulator's format) to serve "
            "while the target does not answer at start; with --list-pvs, list "
            "it without the target.",
        ),
    ] = None,
    list_pvs: Annotated[
        bool,
        typer.Option("--list-pvs", help="Print every PV with type and source; exit."),
    ] = False,
    list_format: Annotated[
        PvListFormat,
        typer.Option(
            "--format",
            case_sensitive=False,
            metavar="[text|archiver|autosave]",
            help="What --list-pvs prints: the PV list, an Archiver Appliance "
            "archivePV list (JSON) or an autosave request file.",
        ),
    ] = PvListFormat.TEXT,
    log_level: LogLevelOption = None,
    graylog_endpoint: Annotated[
        str | None,
        typer.Option(
            "--graylog-endpoint",
            metavar="HOST:PORT",
            help="Also send the log lines to this Graylog GELF UDP input "
            "(FastCS's option).",
        ),
    ] = None,
    graylog_static_fields: Annotated[
        str | None,
        typer.Option(
            "--graylog-static-fields",
            metavar="K:V,...",
            help="Fields with fixed values added to each Graylog message.",
        ),
    ] = None,
    graylog_env_fields: Annotated[
        str | None,
        typer.Option(
            "--graylog-env-fields",
            metavar="K:ENV,...",
            help="Fields added to each Graylog message from the environment.",
        ),
    ] = None,
) -> None:
    """Serve every terminal of a TwinCAT target as EPICS PVs (CA and PVA).

    `ioc schema` prints the JSON schema of the configuration file.
    """
    if context.invoked_subcommand is not None:
        return
    apply_log_level(log_level)
    if graylog_endpoint is not None:
        from fastcs_ethercat.graylog import send_to_graylog

        send_to_graylog(
            str(log_level or logging.getLevelName(logging.getLogger().level)),
            graylog_endpoint,
            graylog_static_fields,
            graylog_env_fields,
        )
    if config is None:
        raise UserError(
            "give the IOC configuration with --config FILE "
            "(`fastcs-ethercat ioc schema` prints its JSON schema)"
        )
    _prepare_ioc_process()
    from fastcs_ethercat.ioc.config import load_ioc_config

    overrides = {
        "prefix": prefix,
        "target": target,
        "ams_net_id": ams_net_id,
        "poll_rate_hz": poll_rate,
        "read_only": True if read_only else None,
        "access_security_file": str(acf) if acf is not None else None,
        "chain": str(chain) if chain is not None else None,
    }
    settings = load_ioc_config(config, overrides)
    _check_installed()  # after the config: a bad file is said before these imports
    from fastcs_ethercat.ioc import app

    if settings.access_security_file is not None:
        _check_acf(settings.access_security_file, settings.read_only)
    if list_pvs:
        entries, warnings = app.list_pvs(settings)
        log_at_most(log, logging.WARNING, warnings, WARNINGS_SHOWN, "warnings")
        sys.stdout.write(
            pv_list_text(
                entries,
                list_format,
                settings.prefix,
                settings.poll_rate_hz,
                settings.archiver.policy(),
            )
        )
        return
    if list_format is not PvListFormat.TEXT:
        raise UserError("--format goes with --list-pvs (or the `pv_lists_dir:` key)")
    app.serve(settings)


def _check_acf(path: Path, read_only: bool) -> None:
    """EPICS's parser accepts the file; a warning for each group of ours it
    leaves to DEFAULT's rules (unless --read-only, which overrides them)."""
    from fastcs_ethercat.ioc.access import check_acf, groups_left_to_default, read_acf

    check_acf(path)
    if read_only:
        return
    for left in groups_left_to_default(read_acf(path)):
        log.warning(
            "%s: no rules for %s: they are writable as DEFAULT allows", path, left
        )


@ioc_app.command("schema")
def schema_command() -> None:
    """Print the JSON schema of the IOC configuration file."""
    from fastcs_ethercat.ioc.config import config_schema_text

    sys.stdout.write(config_schema_text())


def _prepare_ioc_process() -> None:
    """Before the configuration is read and the tree built: the collector
    held until the terminal types are loaded (`app.root_controller`), then
    collecting rarely (see `collector`); pydantic's plugins off unless the
    environment says otherwise (see `PYDANTIC_PLUGINS`)."""
    from fastcs_ethercat import collector

    collector.collect_rarely()
    collector.hold()
    os.environ.setdefault(*PYDANTIC_PLUGINS)


def _check_installed() -> None:
    """The installed FastCS checked, which imports it, softioc and EPICS
    (~1-2 s of CPU): after the configuration, so that a mistake in it is
    said at once."""
    from fastcs_ethercat.ioc.fastcs_adapter import check_installed

    check_installed()


def demo_command(
    prefix: Annotated[
        str, typer.Option("--prefix", metavar="P", help="PV prefix.")
    ] = "DEMO",
    log_level: LogLevelOption = None,
) -> None:
    """Run the simulator with the demo chain and an IOC against it (loopback)."""
    apply_log_level(log_level)
    _prepare_ioc_process()
    _check_installed()
    from fastcs_ethercat.cli.demo_hints import DemoHints, write_pv_list
    from fastcs_ethercat.cli.ports import demo_ports
    from fastcs_ethercat.ioc import app
    from fastcs_ethercat.ioc.config import load_ioc_config
    from fastcs_ethercat.ioc.controllers.root import RootController
    from fastcs_ethercat.sim.process import SimProcess

    for variable, value in EPICS_LOOPBACK_ENV.items():
        os.environ.setdefault(variable, value)
    ports = demo_ports(os.environ)
    os.environ.update(ports.env())
    with SimProcess(chain=DEMO_CHAIN) as sim:
        settings = load_ioc_config(
            DEMO_CONFIG,
            {"prefix": prefix, "target": sim.pyads_ip, "ams_net_id": sim.net_id},
        )

        def ready(root: RootController) -> None:
            entries = root.pvs()
            hints = DemoHints(ports, [entry.name for entry in entries])
            print(f"demo: simulator on {sim.pyads_ip} (NetId {sim.net_id})")
            for line in hints.port_lines():
                print(line)
            print(write_pv_list(prefix, [entry.line() for entry in entries]))
            for line in hints.try_lines():
                print(line)
            print("demo: Ctrl-C to stop", flush=True)

        app.serve(settings, on_ready=ready)
