"""What the IOC of a DIR serves, found the way `ioc --list-pvs` finds it:
DIR's configuration and terminal YAML, DIR/chain.yaml discovered in process
(no network). The same tree gives the screens and the PV lists."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from pathlib import Path

from fastcs_ethercat.ioc.config import IocConfig, load_ioc_config
from fastcs_ethercat.ioc.naming import MAX_PV_LENGTH


@dataclass(frozen=True, slots=True)
class Served:
    """The PVs of DIR's IOC and what it would warn about at start."""

    pv_count: int
    longest: str
    warnings: list[str]
    screens: int

    @property
    def room(self) -> str:
        """`longest PV 52 of 60 characters: NAME`."""
        return (
            f"longest PV name {len(self.longest)} of {MAX_PV_LENGTH} characters: "
            f"{self.longest}"
        )


@dataclass(frozen=True, slots=True)
class Preview:
    """Where DIR's files are: its configuration, its chain, the folders the
    screens and the PV lists go to (in DIR, whatever the configuration says:
    init writes nowhere else)."""

    config: Path
    chain: Path
    screens: Path
    pv_lists: Path


def serve_preview(where: Preview) -> Served:
    """Build DIR's IOC tree from its chain; write its screens and PV lists.
    FastCS is imported as the IOC imports it (`check_installed`: the
    versions checked, the quick way)."""
    from fastcs_ethercat.ioc.fastcs_adapter import check_installed

    config = load_ioc_config(where.config)
    check_installed()
    return asyncio.run(_preview(config, where))


async def _preview(config: IocConfig, where: Preview) -> Served:
    from fastcs_ethercat.ioc.app import root_controller
    from fastcs_ethercat.ioc.boot import chain_source
    from fastcs_ethercat.ioc.pvlists import write_pv_lists

    root = root_controller(
        config, lambda config, registry: chain_source(config, registry, where.chain)
    )
    plan, connection = await root.plan_source()
    try:
        root.build(plan, connection)
        entries = root.pvs()
        warnings = root.warnings()
        from fastcs_ethercat.ioc.screens.chain import write_screens

        screens = write_screens(root, where.screens, ca=config.transports.ca)
        write_pv_lists(where.pv_lists, entries, config.prefix, config.poll_rate_hz)
    finally:
        await connection.pool.close()
    longest = max((entry.name for entry in entries), key=len, default="")
    return Served(len(entries), longest, warnings, screens)
