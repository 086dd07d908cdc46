"""The simulator reached without a socket: the IOC's own ADS client, in process.

`SimConnection` is an `AmsTcpConnection` whose byte stream is a `SimTarget`
in this process: every frame the client writes is reassembled, answered by
`SimTarget.handle` and the answers are fed back on the next turn of the
loop, exactly as they would arrive over TCP. The IOC uses it to discover a
chain file as if it were the PLC (booting without the PLC, `ioc --chain`):
the same discovery code, the same symbol tables TwinCAT would give, and no
port opened.

    async with sim_clients(target) as clients:
        plan = await discover(clients, registry, config, net_id)
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any, Final

from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ads.connection import AmsTcpConnection
from fastcs_ethercat.ads.frames import FrameReassembler, encode_packet
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.twincat.target import SimTarget

IN_PROCESS_HOST: Final = "in-process"
"""The `host` of an in-process connection, as messages show it."""
CLIENT_NET_ID: Final = AmsNetId.parse("127.0.0.1.1.2")
"""Where the in-process client's requests come from (any NetId works)."""


class _SimTransport(asyncio.Transport):
    """Frames written go to the target; its answers come back as received
    data on the next turn of the loop (never inside `write`)."""

    def __init__(self, target: SimTarget, protocol: asyncio.Protocol) -> None:
        super().__init__()
        self._target = target
        self._protocol = protocol
        self._frames = FrameReassembler()
        self._closing = False
        self._loop = asyncio.get_running_loop()

    def write(self, data: bytes | bytearray | memoryview) -> None:
        if self._closing:
            return
        answers = [
            encode_packet(answer)
            for packet in self._frames.feed(bytes(data))
            if (answer := self._target.handle(packet)) is not None
        ]
        if answers:
            self._loop.call_soon(self._deliver, b"".join(answers))

    def _deliver(self, data: bytes) -> None:
        if not self._closing:
            self._protocol.data_received(data)

    def is_closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        if not self._closing:
            self._closing = True
            self._loop.call_soon(self._protocol.connection_lost, None)

    def abort(self) -> None:
        self.close()

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        return default


class SimConnection(AmsTcpConnection):
    """An AMS connection to a `SimTarget` of this process."""

    def __init__(self, target: SimTarget) -> None:
        super().__init__(IN_PROCESS_HOST, 0, local_net_id=CLIENT_NET_ID)
        self.target = target

    async def open_stream(
        self, protocol_factory: Callable[[], asyncio.Protocol]
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        protocol = protocol_factory()
        transport = _SimTransport(self.target, protocol)
        protocol.connection_made(transport)
        return transport, protocol


@contextlib.asynccontextmanager
async def sim_clients(
    target: SimTarget,
) -> AsyncIterator[Callable[[str, int], Awaitable[AdsClient]]]:
    """A client factory (`await clients(net_id, ams_port)`) over one
    in-process connection to `target`; every client closed afterwards."""
    connection = SimConnection(target)
    opened: dict[tuple[str, int], AdsClient] = {}

    async def clients(net_id: str, ams_port: int) -> AdsClient:
        key = (str(net_id), ams_port)
        client = opened.get(key)
        if client is None:
            client = opened[key] = AdsClient(
                IN_PROCESS_HOST, net_id, ams_port, connection=connection
            )
            await client.open()
        return client

    try:
        yield clients
    finally:
        await asyncio.gather(*(client.close() for client in opened.values()))
        await connection.close()


__all__ = ["SimConnection", "sim_clients"]
