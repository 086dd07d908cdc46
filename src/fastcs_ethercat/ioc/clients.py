"""One open `AdsClient` per (NetId, port) for the life of the IOC.

AdsLib keeps one route per NetId per process and `Connection.close()` deletes
it, so closing one connection can cut off another to the same NetId. The pool
hands out shared, open clients and closes them all together at the end.
"""

from __future__ import annotations

import asyncio
import ctypes
from collections.abc import Awaitable, Callable
from typing import Protocol, TypeVar

import pyads

from fastcs_ethercat.ads.client import AdsClient, ads_error
from fastcs_ethercat.ads.constants import ADS_TCP_PORT, AdsReturnCode

_T = TypeVar("_T")

ClientFactory = Callable[[str, int], Awaitable[AdsClient]]
"""`await factory(net_id, ams_port)` -> an open client the factory owns."""


def split_target(target: str) -> tuple[str, int]:
    """`host` or `host:port` (ADS TCP) -> (host, port)."""
    host, _, port = target.rpartition(":")
    if host and port.isdigit():
        return host, int(port)
    return target, ADS_TCP_PORT


class ClientPool:
    """Shared open clients to one router address (`host:tcp_port`)."""

    def __init__(
        self, host: str, tcp_port: int = ADS_TCP_PORT, timeout_ms: int | None = None
    ) -> None:
        self.host = host
        self.tcp_port = tcp_port
        self.timeout_ms = timeout_ms
        self._clients: dict[tuple[str, int], AdsClient] = {}
        self._lock = asyncio.Lock()

    @classmethod
    def for_target(cls, target: str, timeout_ms: int | None = None) -> ClientPool:
        host, port = split_target(target)
        return cls(host, port, timeout_ms)

    async def get(self, net_id: str, ams_port: int) -> AdsClient:
        """The open client for `net_id:ams_port` (opened on first use)."""
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
                )
                await client.open()
                self._clients[key] = client
            return client

    __call__ = get

    async def close(self) -> None:
        """Close every client and remove every route they added."""
        clients, self._clients = list(self._clients.values()), {}
        for client in clients:  # one at a time: AdsLib's port close is not
            await client.close()  # safe from several threads at once
        if clients:
            await asyncio.to_thread(
                _forget_routes,
                [str(client.ams_net_id) for client in clients],
                f"{self.host}:{self.tcp_port}"
                if self.tcp_port != ADS_TCP_PORT
                else self.host,
            )

    async def __aenter__(self) -> ClientPool:
        return self

    async def __aexit__(self, *_: object) -> None:
        await self.close()


def _forget_routes(net_ids: list[str], router_address: str) -> None:
    """Drop the routes AdsLib keeps after every connection closed.

    AdsLib counts routes per router address, not per NetId: closing a
    connection decrements the shared count and only the close that reaches
    zero removes its own NetId's route. The others stay, pointing at this
    address, and a later route to the same NetId through another address (the
    next simulator) fails with 0x506. Re-adding and deleting each one alone
    brings the count to zero for it. Assumes this pool owned every connection
    to the address.
    """
    last = net_ids[-1]
    for net_id in dict.fromkeys(net_ids):
        if net_id != last:
            pyads.add_route(net_id, router_address)
            pyads.delete_route(pyads.AmsAddr(net_id))


async def read_text(
    client: AdsClient, index_group: int, index_offset: int, max_size: int = 255
) -> bytes:
    """Up to `max_size` bytes of a variable-length answer (names, strings).

    `AdsClient.read` insists on the exact size, but a name's length is not
    known in advance: ask pyads for `max_size` without its length check and
    keep the zero padding for the caller to cut at the first NUL.
    TODO(client owner): an `exact=False` on `AdsClient.read` would replace this.
    """
    connection = client._connection
    buffer_type = ctypes.c_ubyte * max_size

    def read() -> bytes:
        raw = connection.read(
            index_group,
            index_offset,
            buffer_type,
            return_ctypes=True,
            check_length=False,
        )
        if raw is None:
            raise RuntimeError("the connection is not open")
        return bytes(raw)

    return await client._call(f"read 0x{index_group:X}:0x{index_offset:X}", read)


class BlockingReader(Protocol):
    """One ADS read on the client's worker thread (inside `in_one_job`)."""

    def __call__(
        self, index_group: int, index_offset: int, size: int, *, exact: bool = True
    ) -> bytes:
        """`size` bytes (`exact`), or up to `size` zero-padded (names, strings);
        raises `AdsError` as `AdsClient.read` would."""
        ...


async def in_one_job(
    client: AdsClient, operation: str, work: Callable[[BlockingReader], _T]
) -> _T:
    """Run `work` on the client's worker thread with a blocking reader.

    Discovery reads a few small values per slave, one round trip each; run
    one by one from the event loop, every read also costs two thread hops.
    Here a whole series costs two. Each read still raises its own `AdsError`
    (`work` decides which ones it survives); anything else ends the job.
    TODO(client owner): a batch call on `AdsClient` would replace this.
    """
    connection = client._connection

    def read(
        index_group: int, index_offset: int, size: int, *, exact: bool = True
    ) -> bytes:
        try:
            raw = connection.read(
                index_group,
                index_offset,
                ctypes.c_ubyte * size,
                return_ctypes=True,
                check_length=exact,
            )
        except pyads.ADSError as error:
            code = getattr(error, "err_code", AdsReturnCode.CLIENT_ERROR)
            where = f"read 0x{index_group:X}:0x{index_offset:X}"
            raise ads_error(code, where, client.target) from error
        if raw is None:
            raise RuntimeError("the connection is not open")
        return bytes(raw)

    return await client._call(operation, lambda: work(read))
