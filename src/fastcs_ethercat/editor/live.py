"""Which PDO group each live terminal runs, for `terminals edit --target`.

The IOC's own discovery answers it (masters, slaves, the live symbol table,
the group whose symbols exist), so the editor reports exactly what an IOC
started on the same files would serve.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from pathlib import Path

from fastcs_ethercat.errors import UserError

LIVE_TIMEOUT_MS = 5000
"""One discovery at start: patience costs nothing, a spurious timeout would."""


@dataclass(frozen=True)
class LiveTerminal:
    """One terminal on the target."""

    name: str
    """TwinCAT name, `Term 5 (EL3104)`."""
    type_name: str | None
    """The terminal YAML type it matched, None when none did."""
    active_group: str | None


def read_live_terminals(
    target: str, directory: Path, ams_net_id: str | None = None
) -> list[LiveTerminal]:
    """Discover the target once (blocking: the editor does it before serving)."""
    from fastcs_ethercat.ioc.boot import discover_once
    from fastcs_ethercat.ioc.config import IocConfig
    from fastcs_ethercat.terminals.loader import load_terminals

    config = IocConfig(
        prefix="EDITOR",
        target=target,
        ams_net_id=ams_net_id,
        terminal_dirs=(directory,),
        ads_timeout_ms=LIVE_TIMEOUT_MS,
    )

    async def go() -> list[LiveTerminal]:
        plan = await discover_once(config, load_terminals((directory,)))
        return [
            LiveTerminal(t.slave.name, t.terminal_type, t.active_group)
            for master in plan.masters
            for t in master.terminals
        ]

    try:
        return asyncio.run(go())
    except UserError:
        raise
    except Exception as error:  # a target that does not answer ADS
        raise UserError(f"cannot read the target {target}: {error}") from None
