"""The IOC's controller tree built in-process from a simulated chain.

The simulator runs on a thread of this process (`SimulatorThread`, loopback
sockets) and the root discovers it as at start-up, but no transport is
started, so tests of names and screens stay in the fast tier.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from fastcs_ethercat.ioc.app import root_controller
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.twincat.target import SimTarget
from tests.conftest import TERMINALS_DIR
from tests.sim_thread import SimulatorThread

BEAMLINE_PREFIX = "BL21I-EA-ECAT-01"
"""A Diamond beamline prefix: 16 characters, as long as they come."""


def chain_text(slaves: list[str], net_id: str = "127.0.0.1.1.1") -> str:
    """A one-master chain file of these terminal types, in bus order."""
    lines = [f"  - type: {slave}" for slave in slaves]
    head = f"system:\n  net_id: {net_id}\nmasters:\n- name: Device 1 (EtherCAT)\n"
    return head + "  slaves:\n" + "\n".join(lines) + "\n"


def built_tree(
    chain: Path, terminals: Path = TERMINALS_DIR, **settings: Any
) -> RootController:
    """The root as the IOC builds it for `chain` (discovered, not served)."""
    target = SimTarget.from_chain(chain, terminals)
    with SimulatorThread(target) as sim:
        config = IocConfig(
            prefix=settings.pop("prefix", BEAMLINE_PREFIX),
            target=f"127.0.0.1:{sim.endpoints.tcp_port}",
            ams_net_id=sim.endpoints.net_id,
            terminal_dirs=(terminals,),
            **settings,
        )

        async def build() -> list[RootController]:
            root = root_controller(config)
            plan, connection = await root.plan_source()
            try:
                root.build(plan, connection)
            finally:
                await connection.pool.close()
            return [root]  # not the root itself: asyncio.run would format it

        [root] = asyncio.run(build())
    return root
