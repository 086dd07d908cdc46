"""The rack as discovery sees it: from the live target, or from a chain file
played in process (no network), both by the IOC's own discovery."""

from __future__ import annotations

import asyncio
from pathlib import Path

from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.terminals.registry import TerminalRegistry


def discover_rack(
    config: IocConfig, registry: TerminalRegistry, from_chain: Path | None
) -> SystemPlan:
    """Every master and slave, matched to `registry`'s YAML (the PDO group
    each runs is told by the live symbols against that YAML's groups)."""
    if from_chain is None:
        from fastcs_ethercat.ioc.boot import discover_once

        return asyncio.run(discover_once(config, registry))
    from fastcs_ethercat.ioc.boot import chain_plan, checked_chain

    chain = checked_chain(from_chain, registry)
    return asyncio.run(
        chain_plan(chain, registry, config, f"the chain file {from_chain}")
    )
