"""One AMS/TCP connection to an ADS router, on asyncio, for many clients.

A TwinCAT router routes by the AMS header, so one TCP connection per target
host carries the requests of every client to every NetId and port behind it.
Each client takes a local AMS port (its notifications are addressed to it);
requests of all clients are in flight at once and matched to their answers
by invoke id in the sans-I/O `ads.session.ClientSession`, which checks every
frame before anything uses it.

The connection opens on the first request and again on the first request
after it was lost: a refused, unreachable or unknown host, a connect timeout,
a dropped connection, a stream that lost its framing each fail the requests
concerned with their own `AdsError` subclass, and nothing else. Malformed
frames are counted per kind (`stats`) and logged at most once a second per
kind.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import socket
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, Protocol, cast

from fastcs_ethercat.ads.commands import AdsRequest, NotificationStamp
from fastcs_ethercat.ads.constants import ADS_TCP_PORT, AdsReturnCode
from fastcs_ethercat.ads.errors import (
    AdsConnectionError,
    AdsConnectionLostError,
    AdsConnectionRefusedError,
    AdsConnectTimeoutError,
    AdsError,
    AdsHostUnreachableError,
    AdsProtocolError,
    AdsTimeoutError,
    AdsUnknownHostError,
)
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.ratelimit import RateLimitedLog
from fastcs_ethercat.ads.session import (
    MAX_FRAME_SIZE,
    Answered,
    BadFrame,
    Broken,
    ClientSession,
    Event,
    Late,
    Malformed,
    Notified,
)

logger = logging.getLogger(__name__)

FIRST_LOCAL_PORT: Final = 30000
"""Local AMS ports are handed out from here (AdsLib's range)."""
CONNECT_TIMEOUT_S: Final = 5.0
MALFORMED_LOG_INTERVAL_S: Final = 1.0
"""At most one log line per this interval about malformed frames, whatever
their kinds (the counts per kind are in `stats`)."""
_UNREACHABLE_ERRNOS: Final = frozenset(
    {errno.EHOSTUNREACH, errno.ENETUNREACH, errno.EHOSTDOWN, errno.ENETDOWN}
)

_default_local_net_id: AmsNetId | None = None
_malformed_logs: dict[str, RateLimitedLog] = {}


def _malformed_log(address: str) -> RateLimitedLog:
    """One limiter per target address for the whole process: a client that
    reconnects again and again to a hostile target still logs at most once
    per interval."""
    log = _malformed_logs.get(address)
    if log is None:
        log = _malformed_logs[address] = RateLimitedLog(
            logger, MALFORMED_LOG_INTERVAL_S
        )
    return log


def set_local_net_id(net_id: str | AmsNetId | None) -> None:
    """This process's AMS NetId for connections opened from now on (None:
    the local IP address towards each target plus `.1.1`, as AdsLib does)."""
    global _default_local_net_id
    _default_local_net_id = (
        net_id
        if net_id is None or isinstance(net_id, AmsNetId)
        else AmsNetId.parse(net_id)
    )


class PortOwner(Protocol):
    """What owns a local AMS port: it gets the notifications sent to it."""

    def notified(
        self, source: AmsAddress, stamps: tuple[NotificationStamp, ...]
    ) -> None:
        """Samples for this port's notification handles (on the loop)."""
        ...

    def connection_lost(self) -> None:
        """Every notification registered through the connection is gone."""
        ...


@dataclass
class ConnectionStats:
    """What a connection has seen, for diagnostics and tests."""

    connects: int = 0
    losses: int = 0
    requests: int = 0
    timeouts: int = 0
    late_answers: int = 0
    notifications: int = 0
    malformed: Counter[Malformed] = field(default_factory=Counter)
    last_heard: float = 0.0
    """time.monotonic() of the last bytes from the target (any frame)."""


@dataclass(slots=True)
class _Waiter:
    future: asyncio.Future[Answered]
    timer: asyncio.TimerHandle
    port: int
    operation: str
    who: str
    on_answer: Callable[[Answered], object] | None


class _Protocol(asyncio.Protocol):
    """Bytes from the socket to the connection, nothing else."""

    def __init__(self, connection: AmsTcpConnection) -> None:
        self.connection = connection

    def data_received(self, data: bytes) -> None:
        self.connection._received(self, data)

    def connection_lost(self, exc: Exception | None) -> None:
        self.connection._lost(self, exc)


class AmsTcpConnection:
    """The TCP connection to one ADS router at `host:tcp_port`."""

    def __init__(
        self,
        host: str,
        tcp_port: int = ADS_TCP_PORT,
        *,
        local_net_id: str | AmsNetId | None = None,
        max_frame_size: int = MAX_FRAME_SIZE,
        connect_timeout_s: float = CONNECT_TIMEOUT_S,
        reconnect: bool = True,
    ) -> None:
        self.host = host
        self.reconnect = reconnect
        """After a loss: connect again with the next request (True), or fail
        every request until closed (False: the owner opens another, e.g. an IOC
        that must re-resolve its symbols first: the target that dropped the
        connection may come back with another configuration)."""
        self.tcp_port = tcp_port
        self.max_frame_size = max_frame_size
        self.connect_timeout_s = connect_timeout_s
        chosen = local_net_id if local_net_id is not None else _default_local_net_id
        self._local_net_id = (
            chosen
            if chosen is None or isinstance(chosen, AmsNetId)
            else AmsNetId.parse(chosen)
        )
        self.stats = ConnectionStats()
        self._log = _malformed_log(self.address)
        self._session = ClientSession(max_frame_size)
        self._transport: asyncio.Transport | None = None
        self._protocol: _Protocol | None = None
        self._connecting: asyncio.Task[None] | None = None
        self._waiting: dict[int, _Waiter] = {}
        self._ports: dict[int, PortOwner] = {}
        self._next_port = FIRST_LOCAL_PORT
        self._closed = False
        self._lost_why: str | None = None

    @property
    def address(self) -> str:
        """`host:tcp_port`, for messages."""
        return f"{self.host}:{self.tcp_port}"

    @property
    def connected(self) -> bool:
        return self._transport is not None and not self._transport.is_closing()

    @property
    def local_net_id(self) -> AmsNetId | None:
        """Our NetId (known once connected, unless given)."""
        return self._local_net_id

    def __repr__(self) -> str:
        return f"AmsTcpConnection({self.address})"

    # -- local ports ---------------------------------------------------------

    def open_port(self, owner: PortOwner) -> int:
        """A local AMS port for `owner` (its requests come from it)."""
        port = self._next_port
        while port in self._ports:
            port = port + 1 if port < 0xFFFF else FIRST_LOCAL_PORT
        self._next_port = port + 1 if port < 0xFFFF else FIRST_LOCAL_PORT
        self._ports[port] = owner
        return port

    def close_port(self, port: int) -> None:
        """Release `port`; its requests in flight fail as closed."""
        self._ports.pop(port, None)
        for invoke_id, waiter in list(self._waiting.items()):
            if waiter.port == port:
                self._finish(
                    invoke_id,
                    AdsConnectionError(
                        AdsReturnCode.CLIENT_PORT_NOT_OPEN,
                        waiter.operation,
                        waiter.who,
                        "the client was closed",
                    ),
                )

    # -- requests --------------------------------------------------------------

    async def connect(self) -> None:
        """Open the TCP connection unless it is open (one attempt for all
        who ask at the same time)."""
        if self._closed:
            raise AdsConnectionError(
                AdsReturnCode.CLIENT_PORT_NOT_OPEN,
                "connect",
                self.address,
                "the connection was closed",
            )
        if self.connected:
            return
        if self._lost_why is not None:
            raise AdsConnectionLostError(
                AdsReturnCode.SOCKET_CONNECTION_RESET,
                "connect",
                self.address,
                message=f"the connection to {self.address} was {self._lost_why}; "
                "not connecting again until reopened",
            )
        if self._connecting is None:
            task = asyncio.get_running_loop().create_task(self._connect())
            task.add_done_callback(self._connect_done)
            self._connecting = task
        await asyncio.shield(self._connecting)

    async def request(
        self,
        target: AmsAddress,
        port: int,
        request: AdsRequest,
        *,
        timeout_s: float,
        operation: str,
        who: str,
        on_answer: Callable[[Answered], object] | None = None,
    ) -> Answered:
        """Send `request` from local `port` to `target`; its answer.

        `on_answer` runs the moment the answer is read, before any later frame
        is looked at (a notification handle is registered there, so its first
        sample always finds it). Raises the `AdsError` of whatever failed.
        """
        await self.connect()
        transport = self._transport
        if transport is None or port not in self._ports:
            raise AdsConnectionError(
                AdsReturnCode.CLIENT_PORT_NOT_OPEN, operation, who, "not open"
            )
        local = self._local_net_id
        assert local is not None  # set on connect
        invoke_id, frame = self._session.send(target, AmsAddress(local, port), request)
        loop = asyncio.get_running_loop()
        future: asyncio.Future[Answered] = loop.create_future()
        timer = loop.call_later(timeout_s, self._expire, invoke_id, timeout_s)
        self._waiting[invoke_id] = _Waiter(
            future, timer, port, operation, who, on_answer
        )
        self.stats.requests += 1
        transport.write(frame)
        try:
            return await future
        except asyncio.CancelledError:
            self._session.forget(invoke_id)
            self._drop_waiter(invoke_id)
            raise

    async def close(self) -> None:
        """Close the socket; every request in flight fails, none is accepted."""
        self._closed = True  # a connect under way closes what it opens
        transport = self._transport
        self._fail_all(
            lambda waiter: AdsConnectionError(
                AdsReturnCode.CLIENT_PORT_NOT_OPEN,
                waiter.operation,
                waiter.who,
                "the connection was closed",
            )
        )
        if transport is not None:
            transport.close()
        self._transport = None
        self._protocol = None

    # -- connecting ------------------------------------------------------------

    async def _connect(self) -> None:
        transport, protocol = await self.open_stream(lambda: _Protocol(self))
        if self._closed:
            transport.close()
            raise self._cannot_reach(
                AdsConnectionError,
                AdsReturnCode.CLIENT_PORT_NOT_OPEN,
                "the connection was closed",
            )
        sock = transport.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            if self._local_net_id is None:
                self._local_net_id = AmsNetId.from_ip(sock.getsockname()[0])
        self._transport = cast(asyncio.Transport, transport)
        self._protocol = cast(_Protocol, protocol)
        self._session = ClientSession(self.max_frame_size)
        self.stats.connects += 1
        logger.debug("connected to %s as %s", self.address, self._local_net_id)

    async def open_stream(
        self, protocol_factory: Callable[[], asyncio.Protocol]
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        """The byte stream to the router: a TCP connection to `host:tcp_port`.

        The one seam for another stream (the simulator in this process, for
        booting from a chain file); errors are the typed `AdsError`s of why
        the router cannot be reached.
        """
        loop = asyncio.get_running_loop()
        try:
            return await asyncio.wait_for(
                loop.create_connection(protocol_factory, self.host, self.tcp_port),
                self.connect_timeout_s,
            )
        except TimeoutError:
            raise self._cannot_reach(
                AdsConnectTimeoutError,
                AdsReturnCode.SOCKET_CONNECTION_TIMEOUT,
                f"no answer in {self.connect_timeout_s:g} s",
            ) from None
        except ConnectionRefusedError:
            raise self._cannot_reach(
                AdsConnectionRefusedError,
                AdsReturnCode.SOCKET_CONNECTION_REFUSED,
                "connection refused",
            ) from None
        except socket.gaierror:
            raise self._cannot_reach(
                AdsUnknownHostError,
                AdsReturnCode.SOCKET_HOST_NOT_FOUND,
                f"unknown host name {self.host!r}",
            ) from None
        except OSError as error:
            if error.errno in _UNREACHABLE_ERRNOS:
                raise self._cannot_reach(
                    AdsHostUnreachableError,
                    AdsReturnCode.SOCKET_HOST_UNREACHABLE,
                    "no route to host",
                ) from None
            raise self._cannot_reach(
                AdsConnectionError,
                AdsReturnCode.PORT_NOT_CONNECTED,
                error.strerror or str(error),
            ) from None

    def _connect_done(self, task: asyncio.Task[None]) -> None:
        self._connecting = None
        if not task.cancelled():
            task.exception()  # retrieved: every waiter got it already

    def _cannot_reach(
        self, kind: type[AdsConnectionError], code: int, why: str
    ) -> AdsConnectionError:
        return kind(
            code,
            "connect",
            self.address,
            message=f"cannot reach {self.address}: {why}",
        )

    # -- what the socket delivers ----------------------------------------------

    def _received(self, protocol: _Protocol, data: bytes) -> None:
        if protocol is not self._protocol:
            return  # a connection already given up
        self.stats.last_heard = time.monotonic()
        for event in self._session.receive(data):
            self._dispatch(event)

    def _dispatch(self, event: Event) -> None:
        match event:
            case Answered():
                waiter = self._drop_waiter(event.invoke_id)
                if waiter is None:
                    return
                if waiter.on_answer is not None:
                    waiter.on_answer(event)
                if not waiter.future.done():
                    waiter.future.set_result(event)
            case Notified():
                self.stats.notifications += 1
                owner = self._ports.get(event.port)
                if owner is not None:
                    owner.notified(event.source, event.stamps)
            case BadFrame():
                self._malformed(event.kind, event.detail)
                invoke_id = event.invoke_id
                waiter = None if invoke_id is None else self._waiting.get(invoke_id)
                if invoke_id is not None and waiter is not None:
                    self._finish(
                        invoke_id,
                        AdsProtocolError(
                            AdsReturnCode.CLIENT_SYNC_RES_INVALID,
                            waiter.operation,
                            waiter.who,
                            f"{event.kind}: {event.detail}",
                        ),
                    )
            case Late():
                self.stats.late_answers += 1
                logger.debug("%s: late answer to invoke id %d", self, event.invoke_id)
            case Broken():
                self._malformed(event.kind, event.detail)
                self._abandon(f"dropped: {event.detail}")

    def _malformed(self, kind: Malformed, detail: str) -> None:
        """Count it; log it unless a malformed frame of any kind was logged in
        the last second (the next line says how many were held back)."""
        self.stats.malformed[kind] += 1
        self._log.warning(
            "malformed",
            "%s: malformed frame from the target (%s): %s",
            self.address,
            kind,
            detail,
        )

    def _lost(self, protocol: _Protocol, exc: Exception | None) -> None:
        if protocol is not self._protocol:
            return
        self.stats.losses += 1
        self._abandon(f"lost: {exc}" if exc else "closed by the target", lost=True)

    def _abandon(self, why: str, *, lost: bool = False) -> None:
        """Give the connection up: fail what is in flight (the target `lost`
        it, or we dropped a stream we cannot trust), tell the ports; the next
        request connects again, unless `reconnect` is off."""
        if not self.reconnect:
            self._lost_why = why
        transport, self._transport, self._protocol = self._transport, None, None
        if transport is not None:
            transport.abort()
        kind, code = (
            (AdsConnectionLostError, AdsReturnCode.SOCKET_CONNECTION_RESET)
            if lost
            else (AdsProtocolError, AdsReturnCode.CLIENT_SYNC_RES_INVALID)
        )
        self._fail_all(
            lambda waiter: kind(
                code,
                waiter.operation,
                waiter.who,
                message=f"{waiter.operation} on {waiter.who} failed: the "
                f"connection to {self.address} was {why}",
            )
        )
        for owner in list(self._ports.values()):
            owner.connection_lost()

    def _expire(self, invoke_id: int, timeout_s: float) -> None:
        waiter = self._waiting.get(invoke_id)
        if waiter is None:
            return
        self.stats.timeouts += 1
        self._session.forget(invoke_id)
        self._finish(
            invoke_id,
            AdsTimeoutError(
                AdsReturnCode.CLIENT_SYNC_TIMEOUT,
                waiter.operation,
                waiter.who,
                f"no answer in {timeout_s * 1000:g} ms",
            ),
        )
        if self._session.buffered:
            # Part of a frame has waited longer than a whole answer may take:
            # its length field lied, and every later answer would be read as
            # its body. Only a new connection resynchronises.
            self._malformed(
                Malformed.FRAMING,
                f"{self._session.buffered} bytes of a frame never completed",
            )
            self._abandon("dropped: a frame never completed")

    # -- waiters -------------------------------------------------------------------

    def _drop_waiter(self, invoke_id: int) -> _Waiter | None:
        waiter = self._waiting.pop(invoke_id, None)
        if waiter is not None:
            waiter.timer.cancel()
        return waiter

    def _finish(self, invoke_id: int, error: AdsError) -> None:
        waiter = self._drop_waiter(invoke_id)
        self._session.forget(invoke_id)
        if waiter is not None and not waiter.future.done():
            waiter.future.set_exception(error)

    def _fail_all(self, error: Callable[[_Waiter], AdsError]) -> None:
        for invoke_id, waiter in list(self._waiting.items()):
            self._finish(invoke_id, error(waiter))


__all__ = [
    "AmsTcpConnection",
    "ConnectionStats",
    "PortOwner",
    "set_local_net_id",
]
