"""UDP 48899 from the client side: ask a target for its AMS NetId, ask it to
add a route back to us. Packets are the `ads.udp` codec's, the same the
simulator answers; a reply is decoded and checked before it is used, and
anything that is not the awaited reply is ignored, as a target ignores
anything that is not a request.

Why not pyads' `adsGetNetIdForPLC` / `add_route_to_plc`: they are pure
Python, but importing pyads loads AdsLib's native library into the process,
which the IOC otherwise never needs.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import socket
from typing import Final, cast

from pydantic import SecretStr

from fastcs_ethercat.ads.constants import ADS_UDP_PORT, AdsReturnCode
from fastcs_ethercat.ads.errors import (
    AdsCodecError,
    AdsConnectionError,
    AdsConnectionRefusedError,
    AdsHostUnreachableError,
    AdsRouteError,
    AdsTimeoutError,
    AdsUnknownHostError,
)
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.udp import (
    UDP_RESPONSE_FLAG,
    UdpPacket,
    UdpTag,
    add_route_request,
    discover_request,
)

logger = logging.getLogger(__name__)

UDP_TIMEOUT_S: Final = 2.0
DISCOVERY_NET_ID: Final = AmsNetId((1, 1, 1, 1, 1, 1))
"""The NetId a discovery request carries (any will do; pyads sends this)."""


class _Replies(asyncio.DatagramProtocol):
    """Waits for the first datagram that decodes as a reply to `service`."""

    def __init__(self, service: int) -> None:
        self.service = service
        self.reply: asyncio.Future[UdpPacket] = (
            asyncio.get_running_loop().create_future()
        )

    def datagram_received(self, data: bytes, addr: tuple[str | int, int]) -> None:
        try:
            packet = UdpPacket.decode(data)
        except AdsCodecError as error:  # not a reply of ours: ignored
            logger.debug("ignoring a UDP datagram from %s: %s", addr, error)
            return
        if packet.service == self.service | UDP_RESPONSE_FLAG and not self.reply.done():
            self.reply.set_result(packet)

    def error_received(self, exc: Exception) -> None:
        if not self.reply.done():
            self.reply.set_exception(exc)


async def exchange(
    host: str,
    request: UdpPacket,
    operation: str,
    *,
    port: int = ADS_UDP_PORT,
    timeout_s: float = UDP_TIMEOUT_S,
) -> UdpPacket:
    """Send `request` to `host:port` and return its reply."""
    target = f"{host}:{port}"
    loop = asyncio.get_running_loop()
    try:
        transport, protocol = await loop.create_datagram_endpoint(
            lambda: _Replies(request.base_service), remote_addr=(host, port)
        )
    except OSError as error:
        raise _socket_error(error, operation, target) from None
    replies = cast(_Replies, protocol)
    try:
        transport.sendto(request.encode())
        return await asyncio.wait_for(replies.reply, timeout_s)
    except TimeoutError:
        raise AdsTimeoutError(
            AdsReturnCode.CLIENT_SYNC_TIMEOUT,
            operation,
            target,
            f"no reply in {timeout_s:g} s",
        ) from None
    except OSError as error:
        raise _socket_error(error, operation, target) from None
    finally:
        transport.close()


async def discover_net_id(
    host: str, *, port: int = ADS_UDP_PORT, timeout_s: float = UDP_TIMEOUT_S
) -> AmsNetId:
    """Ask `host` for its AMS NetId (service 1 on UDP 48899)."""
    reply = await exchange(
        host,
        discover_request(DISCOVERY_NET_ID),
        "NetId discovery",
        port=port,
        timeout_s=timeout_s,
    )
    return reply.netid


async def add_route(
    host: str,
    *,
    local_net_id: str | AmsNetId,
    host_address: str,
    user: str,
    password: SecretStr,
    route_name: str | None = None,
    port: int = ADS_UDP_PORT,
    timeout_s: float = UDP_TIMEOUT_S,
) -> None:
    """Ask `host` to add a route back to us (service 6 on UDP 48899).

    `host_address` is how the target reaches this host. The password leaves
    its `SecretStr` only to be encoded into the request; it is never logged
    and never part of an exception.
    """
    net_id = (
        local_net_id
        if isinstance(local_net_id, AmsNetId)
        else AmsNetId.parse(local_net_id)
    )
    name = route_name or socket.gethostname()
    logger.info("adding route %s -> %s on %s as %s", name, net_id, host, user)
    request = add_route_request(
        net_id, name, net_id, user, password.get_secret_value(), host_address
    )
    reply = await exchange(host, request, "add route", port=port, timeout_s=timeout_s)
    status = reply.tag(UdpTag.STATUS)
    target = f"{host}:{port}"
    if status is None or len(status.data) != 4:
        raise AdsRouteError(
            AdsReturnCode.CLIENT_SYNC_RES_INVALID,
            "add route",
            target,
            "unexpected reply",
        )
    result = status.as_u32()
    if result != AdsReturnCode.NO_ERROR:
        raise AdsRouteError(
            result,
            "add route",
            target,
            f"user {user!r} or its password was refused",
        )


def local_ip_towards(host: str) -> str:
    """The local IPv4 address the kernel would use to reach `host` (no traffic)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect((host, ADS_UDP_PORT))
        return str(probe.getsockname()[0])


def _socket_error(error: OSError, operation: str, target: str) -> AdsConnectionError:
    kind: type[AdsConnectionError] = AdsConnectionError
    code, why = AdsReturnCode.PORT_NOT_CONNECTED, error.strerror or str(error)
    if isinstance(error, socket.gaierror):
        kind, code = AdsUnknownHostError, AdsReturnCode.SOCKET_HOST_NOT_FOUND
        why = "unknown host name"
    elif isinstance(error, ConnectionRefusedError):
        kind, code = AdsConnectionRefusedError, AdsReturnCode.SOCKET_CONNECTION_REFUSED
        why = "connection refused (nothing listens there)"
    elif error.errno in (errno.EHOSTUNREACH, errno.ENETUNREACH):
        kind, code = AdsHostUnreachableError, AdsReturnCode.SOCKET_HOST_UNREACHABLE
        why = "no route to host"
    return kind(
        code, operation, target, message=f"{operation} on {target} failed: {why}"
    )


__all__ = ["add_route", "discover_net_id", "exchange", "local_ip_towards"]
