"""The client pool: one open `AdsClient` per (NetId, port), all on one TCP
connection to the PLC's router (whether a request may go out is
`ioc.connection`'s).

TwinCAT routes by the AMS header, so the pool keeps one TCP connection to the
target's router and hands out clients for every AMS address behind it (I/O
server, masters, device ports, slave mailboxes) that share it.

A lost connection is not opened again behind the IOC's back: every request
fails (typed `AdsConnectionLostError`) until the pool is closed and used
again, which the IOC's supervision does once it has stopped polling, and
then it resolves every symbol anew (the target may come back with another
configuration). A target that refuses or does not answer is tried again with
every `get`.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ads.connection import AmsTcpConnection
from fastcs_ethercat.ads.constants import ADS_TCP_PORT

ClientFactory = Callable[[str, int], Awaitable[AdsClient]]
"""`await factory(net_id, ams_port)` -> an open client the factory owns."""


class ClientPool:
    """Shared open clients to one router address (`host:tcp_port`)."""

    def __init__(
        self, host: str, tcp_port: int = ADS_TCP_PORT, timeout_ms: int | None = None
    ) -> None:
        self.host = host
        self.tcp_port = tcp_port
        self.timeout_ms = timeout_ms
        self.connection = self._new_connection()
        self._clients: dict[tuple[str, int], AdsClient] = {}
        self._lock = asyncio.Lock()

    async def get(self, net_id: str, ams_port: int) -> AdsClient:
        """The open client for `net_id:ams_port` (opened on first use; raises
        the typed `AdsError` of why the target cannot be reached)."""
        key = (str(net_id), ams_port)
        async with self._lock:
            client = self._clients.get(key)
            if client is None:
                client = AdsClient(
                    self.host,
                    key[0],
                    ams_port,
                    tcp_port=self.tcp_port,
                    timeout_ms=self.timeout_ms,
                    connection=self.connection,
                )
                self._clients[key] = client
            await client.open()
            return client

    __call__ = get

    async def close(self) -> None:
        """Close every client and the connection; the pool can be used again
        (a fresh connection opens with the next `get`)."""
        clients, self._clients = list(self._clients.values()), {}
        await asyncio.gather(*(client.close() for client in clients))
        connection, self.connection = self.connection, self._new_connection()
        await connection.close()

    def _new_connection(self) -> AmsTcpConnection:
        return AmsTcpConnection(self.host, self.tcp_port, reconnect=False)

    async def __aenter__(self) -> ClientPool:
        return self

    async def __aexit__(self, *_: object) -> None:
        await self.close()


async def read_text(
    client: AdsClient, index_group: int, index_offset: int, max_size: int = 255
) -> bytes:
    """Up to `max_size` bytes of a variable-length answer (names, strings);
    the caller cuts at the first NUL."""
    return await client.read(index_group, index_offset, max_size, exact=False)
