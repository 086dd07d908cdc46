"""UDP 48899: target discovery and add-route, answered as TwinCAT answers them.

pyads' `adsGetNetIdForPLC` (discovery) reads the NetId from the reply head;
`add_route_to_plc` looks for the STATUS tag with result 0. A route request
with credentials other than the configured ones is answered with result
0x704 (access denied), which is what a real target sends for a wrong
password. Bytes that are not a request are ignored, as a real target does.
"""

from __future__ import annotations

import asyncio
import logging
import socket
from dataclasses import dataclass
from typing import cast

from fastcs_ethercat.ads.constants import AdsReturnCode
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.udp import (
    UdpPacket,
    UdpTag,
    add_route_reply,
    discover_reply,
)
from fastcs_ethercat.ads.udp import UdpService as UdpServiceId
from fastcs_ethercat.loopback import LOOPBACK

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RouteEntry:
    """A route a client added over UDP (kept for tests to inspect)."""

    name: str
    netid: AmsNetId | None
    host: str
    user: str


class _UdpProtocol(asyncio.DatagramProtocol):
    def __init__(self, service: UdpResponder) -> None:
        self._service = service
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: tuple[str | int, int]) -> None:
        reply = self._service.answer(data)
        if reply is not None and self.transport is not None:
            self.transport.sendto(reply, addr)

    def error_received(self, exc: Exception) -> None:
        log.debug("UDP error: %s", exc)


class UdpResponder:
    """The system service's UDP side: discovery and add-route."""

    def __init__(
        self,
        net_id: AmsNetId,
        *,
        host_name: str | None = None,
        twincat_version: tuple[int, int, int] = (3, 1, 4024),
        credentials: tuple[str, str] | None = None,
    ) -> None:
        self.net_id = net_id
        self.host_name = host_name or socket.gethostname()
        self.twincat_version = twincat_version
        self.credentials = credentials
        """(user, password) a route request must carry; None accepts any."""
        self.routes: list[RouteEntry] = []
        self.ignored = 0
        self.port = 0
        self._transport: asyncio.DatagramTransport | None = None

    async def start(self, host: str = LOOPBACK, port: int = 0) -> None:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: _UdpProtocol(self), local_addr=(host, port)
        )
        self._transport = transport
        self.port = transport.get_extra_info("sockname")[1]

    def close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    def answer(self, data: bytes) -> bytes | None:
        """The reply datagram for a request datagram, or None to stay silent."""
        try:
            request = UdpPacket.decode(data)
        except AdsCodecError as error:
            self.ignored += 1
            log.debug("ignoring UDP datagram: %s", error)
            return None
        if request.is_reply:
            self.ignored += 1
            return None
        try:
            match request.service:
                case UdpServiceId.DISCOVER:
                    reply = discover_reply(
                        self.net_id,
                        self.host_name,
                        self.twincat_version,
                        invoke_id=request.invoke_id,
                    )
                case UdpServiceId.ADD_ROUTE:
                    reply = add_route_reply(
                        self.net_id, self._add_route(request), request.invoke_id
                    )
                case _:
                    self.ignored += 1
                    return None
            return reply.encode()
        except AdsCodecError as error:
            self.ignored += 1
            log.debug("cannot answer UDP request: %s", error)
            return None

    def _add_route(self, request: UdpPacket) -> int:
        def text(tag: UdpTag) -> str:
            value = request.tag(tag)
            return value.as_text() if value is not None else ""

        user, password = text(UdpTag.USER_NAME), text(UdpTag.PASSWORD)
        if self.credentials is not None and (user, password) != self.credentials:
            return AdsReturnCode.DEVICE_INVALID_ACCESS
        netid_tag = request.tag(UdpTag.NETID)
        try:
            netid = AmsNetId.from_bytes(netid_tag.data) if netid_tag else None
        except AdsCodecError:
            return AdsReturnCode.DEVICE_INVALID_DATA
        self.routes.append(
            RouteEntry(text(UdpTag.ROUTE_NAME), netid, text(UdpTag.HOST), user)
        )
        return AdsReturnCode.NO_ERROR
