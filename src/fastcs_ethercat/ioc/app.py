"""The IOC, wired: config -> root controller -> FastCS transports.

    config = load_ioc_config(path, overrides)
    serve(config)           # until SIGINT/SIGTERM
    list_pvs(config)        # connect, discover, return every PV, no EPICS

The root controller does the rest: its start-up discovers the target (on
the loop that then serves, so the ADS clients and FastCS share one event
loop) and builds the tree; once the transports serve it polls, supervises
and reads the CoE values (see `controllers/root.py`, `reconnect.py`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from fastcs_ethercat.ads.client import AdsError
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.controllers.root import PlanSource, RootController
from fastcs_ethercat.ioc.controllers.tree import PvEntry
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.launch import LaunchOptions, run
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.ioc.target import prepare_target
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry


def discovery(config: IocConfig, registry: TerminalRegistry) -> PlanSource:
    """The root's plan source: prepare the target (NetId, route), connect and
    discover everything the live target has."""

    async def discover_target() -> tuple[SystemPlan, Connection]:
        net_id = str(await prepare_target(config))
        pool = ClientPool(config.target_host, config.target_port, config.ads_timeout_ms)
        try:
            plan = await discover(pool, registry, config, net_id)
        except AdsError as error:
            await pool.close()
            raise UserError(
                f"cannot discover the target: {error}", where="target"
            ) from None
        except BaseException:
            await pool.close()
            raise
        return plan, Connection(pool, net_id, read_only=config.read_only)

    return discover_target


def root_controller(config: IocConfig) -> RootController:
    """The root of an IOC that discovers `config`'s target at start-up."""
    registry = load_terminals(config.terminal_dirs)
    return RootController(config, discovery(config, registry), registry)


def serve(
    config: IocConfig,
    *,
    on_ready: Callable[[RootController], object] | None = None,
) -> None:
    """Discover, build and serve until interrupted (this process's one IOC)."""
    root = root_controller(config)

    def ready() -> None:
        root.start()
        if on_ready is not None:
            on_ready(root)

    def built() -> None:
        if config.screens_dir is not None:
            from fastcs_ethercat.ioc.screens.chain import write_screens

            write_screens(root, config.screens_dir, ca=config.transports.ca)

    options = LaunchOptions(
        ca=config.transports.ca,
        pva=config.transports.pva,
        access_security_file=config.access_security_file,
        read_only=config.read_only,
    )
    run(root, config.prefix, options, on_ready=ready, on_built=built)


def list_pvs(config: IocConfig) -> tuple[list[PvEntry], list[str]]:
    """Connect, discover and return every PV and every warning; serve nothing."""

    async def go() -> tuple[list[PvEntry], list[str]]:
        # Return plain lists, not the root: asyncio.run formats its main task's
        # result on the way out, and the repr of a large tree takes minutes.
        root = root_controller(config)
        plan, connection = await root.plan_source()
        try:
            root.build(plan, connection)
            return root.pvs(), root.warnings()
        finally:
            await connection.pool.close()

    return asyncio.run(go())
