"""The controllers' handle on one target: may a request go out now, and to
which client (the sockets and clients themselves are `ioc.clients`' pool).

One `Connection` is shared down the controller tree: the root's plan source
creates it, its `Reconnection` component ties its state to the supervisor's
(and reopens the pool), and every
master and terminal asks it for clients and whether a request may go out.
Nothing below the root ever calls back up; a master that sees a whole poll
cycle fail `wake`s the supervisor through it, and one whose symbol handles
went invalid asks it to `resync`.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field

from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.supervisor import LinkState


@dataclass
class Connection:
    """One target as the controllers see it: the link state, the read-only
    rule, the calls up to the supervisor, and the pool's clients once the
    target is prepared."""

    pool: ClientPool
    net_id: str
    """The target's (system) AMS NetId."""
    read_only: bool = False
    state_of: Callable[[], LinkState] = field(default=lambda: LinkState.CONNECTED)
    """The supervisor's view of the link (set by the root's reconnection)."""
    wake: Callable[[], None] = field(default=lambda: None)
    """Ask the supervisor to probe now (set by the root's reconnection)."""
    prepare: Callable[[], Awaitable[None]] | None = None
    """What must happen once before the first client (the route, when the
    IOC booted without its target); done by the first `client` call."""
    resync: Callable[[str], None] = field(default=lambda why: None)
    """Ask the supervisor to resolve every symbol again, saying why (a
    symbol handle went invalid: the table changed, whatever 0xF008 says)."""

    @property
    def state(self) -> LinkState:
        return self.state_of()

    @property
    def connected(self) -> bool:
        return self.state_of() is LinkState.CONNECTED

    async def client(self, net_id: str, ams_port: int) -> AdsClient:
        """The pool's open client to `net_id:ams_port` (of the moment)."""
        if self.prepare is not None:
            await self.prepare()
            self.prepare = None
        return await self.pool.get(net_id, ams_port)

    def check_readable(self) -> None:
        """Refuse (ConnectionError) while the target is away."""
        if not self.connected:
            raise ConnectionError("target not connected")

    def check_writable(self, what: str) -> None:
        """Refuse a write while read-only (PermissionError) or away."""
        if self.read_only:
            raise PermissionError("read-only IOC: no ADS writes")
        if not self.connected:
            raise ConnectionError(f"target not connected: {what} refused")
