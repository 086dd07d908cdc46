"""The simulator's AMS/TCP server: bytes in, packets to the target, bytes out.

Each client connection reassembles its stream with the codec's
`FrameReassembler`, hands every request to `SimTarget.handle` (or, for
Add/DeleteDeviceNotification, to its own `NotificationRegistry`), and writes
all answers to one read in one `transport.write`. Requests to a NetId the
simulator does not serve get AMS error 0x7 (target machine not found). A
stream that breaks the framing is closed; nothing a client sends stops the
server or disturbs other connections.

Transport faults live here too: drop every connection, refuse connections
for a while (the listening socket is closed, so connects fail like against a
rebooting router), stall (answers are held back and released later) and a
forced ADS error for the notification services the server owns.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Collection
from typing import Final, Protocol, cast

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    AddDeviceNotificationResponse,
    DeleteDeviceNotificationRequest,
    DeleteDeviceNotificationResponse,
    ReadWriteRequest,
    ReadWriteResponse,
    error_packet,
)
from fastcs_ethercat.ads.constants import AdsReturnCode, AmsCommand, IndexGroup
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import AmsPacket, FrameReassembler, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.sums import (
    SumAddNotificationsRequest,
    SumAddNotificationsResponse,
    SumDeleteNotificationsRequest,
    SumDeleteNotificationsResponse,
)
from fastcs_ethercat.loopback import LOOPBACK
from fastcs_ethercat.sim.counters import RequestCounters, request_index_group
from fastcs_ethercat.sim.notifications import HandleAllocator, NotificationRegistry

log = logging.getLogger(__name__)

MAX_REQUEST_SIZE: Final = 8 * 1024 * 1024
"""Largest AMS/TCP frame a client may send; a larger one closes its connection."""

MAX_PENDING_OUTPUT: Final = 64 * 1024 * 1024
"""A client that lets this much of our output pile up unread is disconnected."""

REOPEN_RETRY_SECONDS: Final = 0.1

_ANSWERED_COMMANDS: Final = frozenset(
    {
        AmsCommand.READ_DEVICE_INFO,
        AmsCommand.READ,
        AmsCommand.WRITE,
        AmsCommand.READ_STATE,
        AmsCommand.WRITE_CONTROL,
        AmsCommand.ADD_DEVICE_NOTIFICATION,
        AmsCommand.DELETE_DEVICE_NOTIFICATION,
        AmsCommand.READ_WRITE,
    }
)


_SUM_NOTIFICATION_GROUPS: Final = frozenset(
    {
        IndexGroup.SUMUP_ADD_DEVICE_NOTIFICATION,
        IndexGroup.SUMUP_DELETE_DEVICE_NOTIFICATION,
    }
)
"""Sum commands for notifications: served by the server, which owns them."""


class SimTargetLike(Protocol):
    """What the server needs from the model (`twincat.target.SimTarget`)."""

    @property
    def net_ids(self) -> Collection[AmsNetId]: ...

    def handle(self, packet: AmsPacket) -> AmsPacket | None: ...

    def read(
        self, address: AmsAddress, group: int, offset: int, length: int
    ) -> tuple[int, bytes]: ...


class AmsConnection(asyncio.Protocol):
    """One client's TCP stream: reassembly, dispatch, held output on stall."""

    def __init__(self, server: AmsServer) -> None:
        self._server = server
        self._reassembler = FrameReassembler(server.max_request_size)
        self.notifications = NotificationRegistry(server.target.read, server.handles)
        self.transport: asyncio.Transport | None = None
        self.peer: str = "?"
        self._held: list[bytes] = []
        self._held_size = 0

    # -- asyncio callbacks ---------------------------------------------------

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.Transport, transport)
        peer = transport.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        self._server.connection_opened(self)
        log.debug("connection from %s", self.peer)

    def connection_lost(self, exc: Exception | None) -> None:
        self.notifications.clear()
        self._held.clear()
        self._held_size = 0
        self._server.connection_closed(self)
        log.debug("connection from %s closed (%s)", self.peer, exc or "by peer")

    def data_received(self, data: bytes) -> None:
        try:
            packets = self._reassembler.feed(data)
        except AdsCodecError as error:
            self._server.counters.bad_frames += 1
            log.info("closing %s: %s", self.peer, error)
            self.close()
            return
        answers: list[bytes] = []
        for packet in packets:
            answer = self._server.dispatch(self, packet)
            if answer is not None:
                answers.append(encode_packet(answer))
        if answers:
            self.write(b"".join(answers))

    def pause_writing(self) -> None:
        """A client that does not read gets no more of its requests read."""
        if self.transport is not None:
            self.transport.pause_reading()

    def resume_writing(self) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.resume_reading()

    # -- output ----------------------------------------------------------------

    def write(self, data: bytes) -> None:
        """Send now, or hold while the server stalls."""
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        if self._server.stalled:
            self._held.append(data)
            self._held_size += len(data)
            if self._held_size > MAX_PENDING_OUTPUT:
                log.warning("dropping %s: too much held while stalled", self.peer)
                transport.abort()
            return
        if transport.get_write_buffer_size() > MAX_PENDING_OUTPUT:
            log.warning("dropping %s: %d bytes unread", self.peer, MAX_PENDING_OUTPUT)
            transport.abort()
            return
        transport.write(data)

    def release_held(self) -> None:
        """After a stall: send what was held, in order, in one write."""
        if self._held:
            held, self._held, self._held_size = b"".join(self._held), [], 0
            self.write(held)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()

    def abort(self) -> None:
        if self.transport is not None:
            self.transport.abort()


class AmsServer:
    """Listens on AMS/TCP and serves a target to any number of clients."""

    def __init__(
        self,
        target: SimTargetLike,
        *,
        counters: RequestCounters | None = None,
        max_request_size: int = MAX_REQUEST_SIZE,
        monotonic_ns: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.target = target
        self.counters = counters if counters is not None else RequestCounters()
        self.max_request_size = max_request_size
        self.handles = HandleAllocator()
        self.connections: set[AmsConnection] = set()
        self.host = LOOPBACK
        self.port = 0
        self._monotonic_ns = monotonic_ns
        self._net_ids = frozenset(target.net_ids)
        self._listener: asyncio.Server | None = None
        self._stalled = False
        self._stall_timer: asyncio.TimerHandle | None = None
        self._reopen_task: asyncio.Task[None] | None = None
        self._refusing = False
        self.forced_error: tuple[int, int | None] | None = None
        self.on_request: Callable[[], object] | None = None
        """Called before each request is served (the runner's paced task)."""

    # -- life cycle --------------------------------------------------------------

    async def start(self, host: str = LOOPBACK, port: int = 0) -> None:
        """Listen; port 0 takes a free port (read it back from `port`)."""
        self.host = host
        self.port = port
        await self._listen()

    async def _listen(self) -> None:
        loop = asyncio.get_running_loop()
        self._listener = await loop.create_server(
            lambda: AmsConnection(self), self.host, self.port, reuse_address=True
        )
        self.port = self._listener.sockets[0].getsockname()[1]

    async def close(self) -> None:
        """Stop listening, drop every client, cancel timers."""
        self._cancel_timers()
        self._stalled = False
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        self.drop_connections()

    def connection_opened(self, connection: AmsConnection) -> None:
        self.connections.add(connection)
        self.counters.connections_accepted += 1

    def connection_closed(self, connection: AmsConnection) -> None:
        self.connections.discard(connection)

    # -- requests ----------------------------------------------------------------

    def dispatch(
        self, connection: AmsConnection, packet: AmsPacket
    ) -> AmsPacket | None:
        """The answer to one packet, or None when it needs none."""
        self.counters.count_request(packet)
        if self.on_request is not None:
            self.on_request()
        if packet.is_response or packet.command == AmsCommand.DEVICE_NOTIFICATION:
            return None
        if packet.target.netid not in self._net_ids:
            return packet.response(error_code=AdsReturnCode.TARGET_MACHINE_NOT_FOUND)
        if packet.command == AmsCommand.ADD_DEVICE_NOTIFICATION:
            return self._add_notification(connection, packet)
        if packet.command == AmsCommand.DELETE_DEVICE_NOTIFICATION:
            return self._delete_notification(connection, packet)
        if (
            packet.command == AmsCommand.READ_WRITE
            and request_index_group(packet) in _SUM_NOTIFICATION_GROUPS
        ):
            return self._sum_notifications(connection, packet)
        try:
            answer = self.target.handle(packet)
        except AdsCodecError as error:
            return error_packet(packet, error.return_code)
        except Exception:
            log.exception("target failed on %s", packet)
            return error_packet(packet, AdsReturnCode.DEVICE_ERROR)
        if answer is None and packet.command not in _ANSWERED_COMMANDS:
            return packet.response(
                error_code=AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
            )
        return answer

    def _forced_error_for(self, group: int | None) -> int | None:
        if self.forced_error is None:
            return None
        code, only_group = self.forced_error
        return code if only_group is None or only_group == group else None

    def _add_notification(
        self, connection: AmsConnection, packet: AmsPacket
    ) -> AmsPacket:
        try:
            request = AddDeviceNotificationRequest.decode(packet.payload)
        except AdsCodecError as error:
            return error_packet(packet, error.return_code)
        forced = self._forced_error_for(request.index_group)
        if forced is not None:
            return error_packet(packet, forced)
        try:
            result, handle = connection.notifications.add(
                packet, request, self._monotonic_ns()
            )
        except Exception:
            log.exception("notification registration failed for %s", request)
            return error_packet(packet, AdsReturnCode.DEVICE_ERROR)
        if result == AdsReturnCode.TARGET_PORT_NOT_FOUND:
            # the router answers for a port nobody listens on, not a service
            return packet.response(error_code=result)
        return packet.response(
            payload=AddDeviceNotificationResponse(result, handle).encode()
        )

    def _delete_notification(
        self, connection: AmsConnection, packet: AmsPacket
    ) -> AmsPacket:
        try:
            request = DeleteDeviceNotificationRequest.decode(packet.payload)
        except AdsCodecError as error:
            return error_packet(packet, error.return_code)
        result = connection.notifications.delete(packet, request.handle)
        return packet.response(
            payload=DeleteDeviceNotificationResponse(result).encode()
        )

    def _sum_notifications(
        self, connection: AmsConnection, packet: AmsPacket
    ) -> AmsPacket:
        """0xF085 / 0xF086: add or delete many notifications in one request."""
        try:
            request = ReadWriteRequest.decode(packet.payload)
            count = request.index_offset
            if request.index_group == IndexGroup.SUMUP_ADD_DEVICE_NOTIFICATION:
                adds = SumAddNotificationsRequest.decode(request.data, count).items
                now_ns = self._monotonic_ns()
                pairs = [
                    (forced, 0)
                    if (forced := self._forced_error_for(add.index_group)) is not None
                    else connection.notifications.add(packet, add, now_ns)
                    for add in adds
                ]
                data = SumAddNotificationsResponse(
                    tuple(r for r, _ in pairs), tuple(h for _, h in pairs)
                ).encode()
            else:
                handles = SumDeleteNotificationsRequest.decode(request.data, count)
                data = SumDeleteNotificationsResponse(
                    tuple(
                        connection.notifications.delete(packet, handle)
                        for handle in handles.handles
                    )
                ).encode()
        except AdsCodecError as error:
            return error_packet(packet, error.return_code)
        if len(data) > request.read_length:
            return error_packet(packet, AdsReturnCode.DEVICE_INVALID_SIZE)
        return packet.response(payload=ReadWriteResponse(data=data).encode())

    # -- notifications -------------------------------------------------------------

    def tick(
        self,
        now_ns: int | None = None,
        wall_ns: int | None = None,
        next_tick_ns: int | None = None,
    ) -> None:
        """Sample every connection's notifications; push what is due (by the
        next tick, when its time is given: nothing leaves late)."""
        now_ns = self._monotonic_ns() if now_ns is None else now_ns
        wall_ns = time.time_ns() if wall_ns is None else wall_ns
        send = not self._stalled
        for connection in list(self.connections):
            frames, samples = connection.notifications.tick(
                now_ns, wall_ns, send=send, next_tick_ns=next_tick_ns
            )
            if frames:
                self.counters.count_notifications(len(frames), samples)
                connection.write(b"".join(frames))

    @property
    def notification_count(self) -> int:
        return sum(len(c.notifications) for c in self.connections)

    # -- transport faults ------------------------------------------------------------

    def drop_connections(self) -> int:
        """Close every client connection at once; return how many there were."""
        connections = list(self.connections)
        for connection in connections:
            connection.abort()
        return len(connections)

    def refuse(self, seconds: float) -> None:
        """Drop everyone and stop listening for `seconds`."""
        self._refusing = True
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        self.drop_connections()
        if self._reopen_task is not None:
            self._reopen_task.cancel()
        self._reopen_task = asyncio.get_running_loop().create_task(
            self._reopen_after(seconds)
        )

    async def _reopen_after(self, seconds: float) -> None:
        await asyncio.sleep(seconds)
        while True:
            try:
                await self._listen()
            except OSError as error:
                log.warning(
                    "cannot listen again on %s:%d: %s", self.host, self.port, error
                )
                await asyncio.sleep(REOPEN_RETRY_SECONDS)
            else:
                self._refusing = False
                self._reopen_task = None
                return

    @property
    def stalled(self) -> bool:
        return self._stalled

    def stall(self, seconds: float | None = None) -> None:
        """Hold all output for `seconds` (None: until `clear_faults`)."""
        self._stalled = True
        if self._stall_timer is not None:
            self._stall_timer.cancel()
            self._stall_timer = None
        if seconds is not None:
            self._stall_timer = asyncio.get_running_loop().call_later(
                seconds, self.end_stall
            )

    def end_stall(self) -> None:
        self._stalled = False
        if self._stall_timer is not None:
            self._stall_timer.cancel()
            self._stall_timer = None
        for connection in list(self.connections):
            connection.release_held()

    def force_error(self, code: int, group: int | None = None) -> None:
        """Answer notification requests (of `group`, if given) with `code`."""
        self.forced_error = (code, group)

    def clear_faults(self) -> None:
        """End a stall and a refusal, forget a forced error."""
        self.forced_error = None
        if self._stalled:
            self.end_stall()
        if self._refusing and self._reopen_task is not None:
            self._reopen_task.cancel()
            self._reopen_task = asyncio.get_running_loop().create_task(
                self._reopen_after(0)
            )

    def active_faults(self) -> list[dict[str, object]]:
        faults: list[dict[str, object]] = []
        if self._refusing:
            faults.append({"kind": "refuse"})
        if self._stalled:
            faults.append({"kind": "stall"})
        if self.forced_error is not None:
            code, group = self.forced_error
            faults.append({"kind": "error", "code": code, "group": group})
        return faults

    def _cancel_timers(self) -> None:
        if self._stall_timer is not None:
            self._stall_timer.cancel()
            self._stall_timer = None
        if self._reopen_task is not None:
            self._reopen_task.cancel()
            self._reopen_task = None
        self._refusing = False
