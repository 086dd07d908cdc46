"""The IOC, wired: config -> root controller -> FastCS transports.

    config = load_ioc_config(path, overrides)
    serve(config)           # until SIGINT/SIGTERM
    list_pvs(config)        # discover (or read the chain file), return every PV

The root controller does the rest: its start-up finds the chain (the PLC,
else a configured or cached chain file, `ioc.boot`; on the loop that then
serves, so the ADS clients and FastCS share one event loop) and builds the
tree; once the transports serve it polls, supervises and reads the CoE
values (see `controllers/root.py`, `reconnect.py`).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

from fastcs_ethercat import collector
from fastcs_ethercat.ioc.boot import PlanSource, boot_source, chain_source, live_source
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.ioc.controllers.tree import PvEntry
from fastcs_ethercat.ioc.launch import LaunchOptions, run
from fastcs_ethercat.ioc.process_stats import deviocstats_aliases
from fastcs_ethercat.ioc.pvlists import write_pv_lists
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry

logger = logging.getLogger(__name__)

SourceMaker = Callable[[IocConfig, TerminalRegistry], PlanSource]


def root_controller(
    config: IocConfig, source: SourceMaker = boot_source
) -> RootController:
    """The root of an IOC whose start-up takes its plan from `source`; the
    collector, held through the IOC's imports, collects again before the
    target is asked anything (`collector.hold`)."""
    registry = load_terminals(config.terminal_dirs)
    root = RootController(config, source(config, registry), registry)
    collector.release()
    return root


def serve(
    config: IocConfig,
    *,
    on_ready: Callable[[RootController], object] | None = None,
) -> None:
    """Find the chain, build and serve until interrupted (this process's one
    IOC); the PLC may be away at start (`ioc.boot`)."""
    root = root_controller(config)

    def ready() -> None:
        root.start()
        if config.pv_lists_dir is not None:
            write_lists(root, config)
        if on_ready is not None:
            on_ready(root)

    def built() -> None:
        if config.screens_dir is not None:
            from fastcs_ethercat.ioc.screens.chain import write_screens

            write_screens(root, config.screens_dir, ca=config.transports.ca)

    async def prepare() -> None:
        await root.prepare()

    if config.audit_puts:  # CA or PVA: both put through the database
        from fastcs_ethercat.ioc.audit import install_put_audit

        install_put_audit()
    options = LaunchOptions(
        ca=config.transports.ca,
        pva=config.transports.pva,
        ca_aliases=deviocstats_aliases(config.prefix),
        access_security_file=config.access_security_file,
        read_only=config.read_only,
        site_databases=config.site_databases(),
        autosave_dir=config.autosave_dir,
    )
    try:
        run(
            root,
            config.prefix,
            options,
            on_ready=ready,
            on_built=built,
            on_pvs_built=prepare,
        )
    except asyncio.CancelledError:  # SIGTERM before FastCS serves (the PLC away)
        logger.info("stopped before serving")
    finally:
        if config.autosave_dir is not None:
            from fastcs_ethercat.ioc.fastcs_adapter import stop_autosave

            stop_autosave()


def write_lists(root: RootController, config: IocConfig) -> None:
    """The archiver and autosave files of what serves; a folder that cannot
    be written costs a warning, never the IOC."""
    assert config.pv_lists_dir is not None
    try:
        written = write_pv_lists(
            config.pv_lists_dir,
            root.pvs(),
            config.prefix,
            config.poll_rate_hz,
            config.archiver.policy(),
        )
    except OSError as error:
        logger.warning(
            "cannot write the PV lists in %s: %s", config.pv_lists_dir, error
        )
        return
    logger.info("PV lists written: %s", ", ".join(str(path) for path in written))


def list_pvs(config: IocConfig) -> tuple[list[PvEntry], list[str]]:
    """Every PV and every warning, serving nothing: of the configured chain
    file (the target untouched), else of the target (one attempt)."""
    chain = config.chain

    def source(config: IocConfig, registry: TerminalRegistry) -> PlanSource:
        if chain is not None:
            return chain_source(config, registry, chain)
        return live_source(config, registry)

    async def go() -> tuple[list[PvEntry], list[str]]:
        # Return plain lists, not the root: asyncio.run formats its main task's
        # result on the way out, and the repr of a large tree takes minutes.
        root = root_controller(config, source)
        plan, connection = await root.plan_source()
        try:
            root.build(plan, connection)
            root.keep_chain(plan)
            return root.pvs(), root.warnings()
        finally:
            await connection.pool.close()

    return asyncio.run(go())
