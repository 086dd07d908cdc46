"""Where the IOC's chain comes from at start: the PLC, else a chain file.

The root controller takes its plan from a `PlanSource`; these are the ones
the IOC uses:

- `live_source`: discover the target (NetId, route, masters, symbols); one
  attempt, a `TargetError` if the target cannot be reached or discovered
  (`discover_once` for tools that only look).
- `chain_source`: discover a chain file as if it were the PLC (the simulator
  of that chain, in this process, read by the same discovery code); nothing
  is sent to the target. `ioc --list-pvs --chain FILE` lists it.
- `boot_source`, what `ioc` serves with: the PLC if it answers; else the
  configured `chain:` file, else the chain this target showed last (kept by
  the root after every discovery, `ioc.chains`), served at once with every
  PV INVALID until the supervisor reaches the target; with neither, it waits
  for the PLC, trying again with backoff and saying so at most once per
  `WAIT_LOG_INTERVAL_S`. The IOC never exits because the PLC is away.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from fastcs_ethercat.ads.client import AdsError
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.ratelimit import RateLimitedLog
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.chains import cache_path, cached_chain
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.ioc.supervisor import Backoff
from fastcs_ethercat.ioc.target import TargetError, prepare_target
from fastcs_ethercat.terminals.registry import TerminalRegistry

if TYPE_CHECKING:  # chain files are read only without the PLC or with `chain:`
    from fastcs_ethercat.chain.file import Chain

logger = logging.getLogger(__name__)

PlanSource = Callable[[], Coroutine[Any, Any, tuple[SystemPlan, Connection]]]
"""What the root serves and how it reaches the target."""
WAIT_LOG_INTERVAL_S: Final = 10.0
"""At most one line per this interval while waiting for the PLC at start."""
WAIT_BACKOFF: Final = Backoff(first_s=0.5, factor=2.0, most_s=5.0)


def live_source(config: IocConfig, registry: TerminalRegistry) -> PlanSource:
    """Prepare the target (NetId, route), connect, discover what it has."""

    async def discover_target() -> tuple[SystemPlan, Connection]:
        started = time.monotonic()
        logger.debug("discovering %s", config.target)
        net_id = str(await prepare_target(config))
        pool = ClientPool(config.target_host, config.target_port, config.ads_timeout_ms)
        try:
            plan = await discover(pool, registry, config, net_id)
        except (AdsError, AdsCodecError) as error:
            await pool.close()
            raise TargetError(
                f"cannot discover the target: {error}", where="target"
            ) from None
        except BaseException:
            await pool.close()
            raise
        _log_discovered(plan, config.target, started)
        return plan, Connection(pool, net_id, read_only=config.read_only)

    return discover_target


async def discover_once(config: IocConfig, registry: TerminalRegistry) -> SystemPlan:
    """The target as discovered now; its connections closed again (tools:
    `chain dump`, the editor's live view)."""
    plan, connection = await live_source(config, registry)()
    await connection.pool.close()
    return plan


async def chain_plan(
    chain: Chain, registry: TerminalRegistry, config: IocConfig, origin: str
) -> SystemPlan:
    """What discovery would find on a PLC that runs `chain` (no network)."""
    from fastcs_ethercat.twincat.inprocess import sim_clients
    from fastcs_ethercat.twincat.resolve import revisions_of
    from fastcs_ethercat.twincat.target import SimTarget

    target = SimTarget(chain, registry, revisions=revisions_of(registry))
    async with sim_clients(target) as clients:
        plan = await discover(clients, registry, config, str(target.system_net_id))
    plan.offline_from = origin
    plan.device_name = plan.device_version = ""  # the PLC's, once it answers
    plan.symbol_version = 0
    return plan


def chain_source(
    config: IocConfig, registry: TerminalRegistry, path: Path
) -> PlanSource:
    """The chain file at `path`, discovered in process; the target untouched
    (the connection is made only when something asks for a client)."""

    async def from_file() -> tuple[SystemPlan, Connection]:
        from fastcs_ethercat.chain.file import load_chain

        origin = f"the chain file {path}"
        plan = await chain_plan(load_chain(path), registry, config, origin)
        return plan, _offline_connection(config, plan)

    return from_file


def boot_source(config: IocConfig, registry: TerminalRegistry) -> PlanSource:
    """The PLC; while it does not answer, the configured or cached chain;
    with neither, wait for the PLC (see the module's docstring). A configured
    chain that does not load stops the IOC at every start, not only on the
    day the PLC is away."""
    discover_live = live_source(config, registry)

    async def boot() -> tuple[SystemPlan, Connection]:
        configured = (
            None if config.chain is None else checked_chain(config.chain, registry)
        )
        pauses = WAIT_BACKOFF.pauses()
        waiting = RateLimitedLog(logger, WAIT_LOG_INTERVAL_S)
        started = time.monotonic()
        logger.info("discovering %s", config.target)
        while True:
            try:
                return await discover_live()
            except TargetError as error:
                why = str(error)
            offline = await _offline_plan(config, registry, configured, why)
            if offline is not None:
                return offline
            waiting.warning(
                "wait",
                "%s; nothing to serve until it answers (no `chain:` in the config "
                "and no chain kept from an earlier start): trying again, %.0f s "
                "since start",
                why,
                time.monotonic() - started,
            )
            await asyncio.sleep(pauses())

    return boot


def checked_chain(path: Path, registry: TerminalRegistry) -> Chain:
    """The chain file at `path`, its types known to `registry` (else a
    one-line `UserError` naming the file and line)."""
    from fastcs_ethercat.chain.file import load_chain
    from fastcs_ethercat.twincat.resolve import resolve_chain

    chain = load_chain(path)
    resolve_chain(chain, registry)
    return chain


async def _offline_plan(
    config: IocConfig,
    registry: TerminalRegistry,
    configured: Chain | None,
    why: str,
) -> tuple[SystemPlan, Connection] | None:
    """The configured chain, else the cached one, as a plan to serve now."""
    from fastcs_ethercat.twincat.resolve import resolve_chain

    if configured is not None:
        chain, origin = configured, f"the chain file {config.chain}"
    else:
        chain = cached_chain(config.target)
        origin = f"the chain kept from the last start ({cache_path(config.target)})"
        if chain is None:
            return None
        try:
            resolve_chain(chain, registry)
        except UserError as error:  # the terminal YAML changed since
            logger.warning("ignoring the cached chain: %s", error)
            return None
    plan = await chain_plan(chain, registry, config, origin)
    terminals = sum(len(master.terminals) for master in plan.masters)
    logger.warning(
        "%s; serving %d terminals from %s, every PV INVALID until the target answers",
        why,
        terminals,
        origin,
    )
    return plan, _offline_connection(config, plan)


def _offline_connection(config: IocConfig, plan: SystemPlan) -> Connection:
    """A connection that prepares the target (route, NetId) on first use."""
    pool = ClientPool(config.target_host, config.target_port, config.ads_timeout_ms)
    connection = Connection(
        pool, config.ams_net_id or plan.net_id, read_only=config.read_only
    )

    async def prepare() -> None:
        connection.net_id = str(await prepare_target(config))

    connection.prepare = prepare
    return connection


def _log_discovered(plan: SystemPlan, target: str, started: float) -> None:
    terminals = sum(len(master.terminals) for master in plan.masters)
    logger.info(
        "discovered %d terminals on %d master(s) of %s in %.1f s",
        terminals,
        len(plan.masters),
        target,
        time.monotonic() - started,
    )
