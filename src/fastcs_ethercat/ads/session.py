"""The client side of one AMS/TCP connection as a sans-I/O state machine.

`ClientSession.send` turns a request into frame bytes under a fresh invoke id;
`ClientSession.receive` turns whatever the socket read into events. Every
byte from the peer is checked here, in pure Python, before anything uses it:
the AMS/TCP length against a maximum frame size, the AMS header against the
frame (data length, response flag, command id), the invoke id against the
requests in flight, the source and command against the request, and the
payload against the command's layout and the length asked for. A frame that
fails one of these is a `BadFrame` (its `Malformed` kind and a detail) and
dropped; if it answered a request in flight, that request fails. When the
AMS/TCP framing itself is lost (a length beyond the limit, a non-zero
reserved field) the stream cannot be resynchronised: `Broken` ends it and
every request in flight fails with it. The asyncio layer
(`ads.connection`) owns the socket, the futures and the timers.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Final

from fastcs_ethercat.ads.commands import (
    AdsRequest,
    AdsResponse,
    DeviceNotification,
    NotificationStamp,
    ReadRequest,
    ReadResponse,
    ReadWriteRequest,
    ReadWriteResponse,
    decode_response,
)
from fastcs_ethercat.ads.constants import (
    REQUEST_FLAGS,
    AdsReturnCode,
    AmsCommand,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import (
    AmsPacket,
    FrameReassembler,
    FrameTooLargeError,
    decode_ams,
    encode_packet,
    header_invoke_id,
)
from fastcs_ethercat.ads.netid import AmsAddress

MAX_FRAME_SIZE: Final = 32 * 1024 * 1024
"""Largest AMS/TCP frame a client accepts (a symbol table of ~100 000 I/O
symbols fits); a larger length field ends the connection."""
MAX_INVOKE_ID: Final = 0xFFFF_FFFF
FORGOTTEN_REMEMBERED: Final = 4096
"""Invoke ids given up on that are still recognised when their answer comes."""


class Malformed(StrEnum):
    """Kinds of bad frames (one rate-limited log line per kind)."""

    FRAMING = "framing"
    """AMS/TCP header unusable (reserved field, length below the AMS header)."""
    OVERSIZE = "oversize"
    """AMS/TCP length beyond the maximum frame size."""
    HEADER = "ams header"
    """AMS header disagrees with its frame (data length) or is cut short."""
    UNEXPECTED = "unexpected frame"
    """A request, or a command a client never receives."""
    INVOKE_ID = "unknown invoke id"
    """A response to no request in flight (late after a timeout, or bogus)."""
    MISMATCH = "mismatched response"
    """Another command or address than the request it answers."""
    PAYLOAD = "payload"
    """A payload that breaks its command's layout or the length asked for."""
    NOTIFICATION = "notification"
    """A DeviceNotification whose stream does not parse."""


@dataclass(frozen=True, slots=True)
class Answered:
    """The response to request `invoke_id` (its AMS error code may be set)."""

    invoke_id: int
    packet: AmsPacket
    response: AdsResponse | None
    """None when the AMS header carries an error and no payload."""


@dataclass(frozen=True, slots=True)
class Notified:
    """A DeviceNotification for our port `port` from `source`."""

    port: int
    source: AmsAddress
    stamps: tuple[NotificationStamp, ...]


@dataclass(frozen=True, slots=True)
class BadFrame:
    """A malformed frame, dropped; when it answered request `invoke_id`,
    that request fails with it."""

    kind: Malformed
    detail: str
    invoke_id: int | None = None


@dataclass(frozen=True, slots=True)
class Late:
    """The answer to a request given up on (timed out): not an error."""

    invoke_id: int


@dataclass(frozen=True, slots=True)
class Broken:
    """The stream lost its framing: close it; `failed` were in flight."""

    kind: Malformed
    detail: str
    failed: tuple[int, ...]


Event = Answered | Notified | BadFrame | Late | Broken


@dataclass(frozen=True, slots=True)
class _InFlight:
    target: AmsAddress
    source: AmsAddress
    command: AmsCommand
    max_data: int | None
    """Most data bytes the answer may carry (Read, ReadWrite), if bounded."""


class ClientSession:
    """Invoke ids, requests in flight and frame checks of one connection."""

    def __init__(self, max_frame_size: int = MAX_FRAME_SIZE) -> None:
        self._reassembler = FrameReassembler(max_frame_size)
        self._in_flight: dict[int, _InFlight] = {}
        self._forgotten: dict[int, None] = {}
        self._next_invoke_id = 1

    @property
    def buffered(self) -> int:
        """Bytes of an incomplete frame waiting for the rest."""
        return self._reassembler.buffered

    def send(
        self, target: AmsAddress, source: AmsAddress, request: AdsRequest
    ) -> tuple[int, bytes]:
        """A fresh invoke id and the frame that carries `request`."""
        invoke_id = self._allocate()
        frame = encode_packet(
            AmsPacket(
                target=target,
                source=source,
                command=request.command,
                state_flags=REQUEST_FLAGS,
                invoke_id=invoke_id,
                payload=request.encode(),
            )
        )
        self._in_flight[invoke_id] = _InFlight(
            target, source, request.command, _max_data(request)
        )
        return invoke_id, frame

    def forget(self, invoke_id: int) -> None:
        """Stop waiting for `invoke_id` (timed out, cancelled): a late answer
        is then reported as `Late`."""
        if self._in_flight.pop(invoke_id, None) is not None:
            self._forgotten[invoke_id] = None
            if len(self._forgotten) > FORGOTTEN_REMEMBERED:
                del self._forgotten[next(iter(self._forgotten))]

    def receive(self, data: bytes | bytearray | memoryview) -> list[Event]:
        """Everything `data` completes, in order of arrival; `Broken` last
        where the framing broke (the frames before it still count)."""
        reassembler = self._reassembler
        try:
            frames = reassembler.split(data)
        except AdsCodecError:  # already broken: nothing more is read
            return []
        events = [self._frame(body) for body in frames]
        error = reassembler.broken
        if error is not None:
            kind = (
                Malformed.OVERSIZE
                if isinstance(error, FrameTooLargeError)
                else Malformed.FRAMING
            )
            failed = tuple(self._in_flight)
            self._in_flight.clear()
            events.append(Broken(kind, str(error), failed))
        return events

    # -- one frame -----------------------------------------------------------

    def _frame(self, body: bytes) -> Event:
        try:
            packet = decode_ams(body)
        except AdsCodecError as error:
            return self._fail(header_invoke_id(body), Malformed.HEADER, str(error))
        if not packet.is_response:
            if packet.command == AmsCommand.DEVICE_NOTIFICATION:
                return self._notification(packet)
            return BadFrame(
                Malformed.UNEXPECTED,
                f"request (command {int(packet.command)}) from {packet.source}",
            )
        request = self._in_flight.get(packet.invoke_id)
        if request is None:
            if packet.invoke_id in self._forgotten:
                del self._forgotten[packet.invoke_id]
                return Late(packet.invoke_id)
            return BadFrame(
                Malformed.INVOKE_ID,
                f"response with invoke id {packet.invoke_id} to no request",
            )
        if packet.command != request.command:
            return self._fail(
                packet.invoke_id,
                Malformed.MISMATCH,
                f"command {int(packet.command)} answers a "
                f"{request.command.name} request",
            )
        if packet.source != request.target or packet.target != request.source:
            return self._fail(
                packet.invoke_id,
                Malformed.MISMATCH,
                f"response from {packet.source} to {packet.target} answers a "
                f"request from {request.source} to {request.target}",
            )
        if packet.error_code != AdsReturnCode.NO_ERROR and not packet.payload:
            del self._in_flight[packet.invoke_id]
            return Answered(packet.invoke_id, packet, None)
        try:
            response = decode_response(int(packet.command), packet.payload)
            _check_length(response, request.max_data)
        except AdsCodecError as error:
            return self._fail(packet.invoke_id, Malformed.PAYLOAD, str(error))
        del self._in_flight[packet.invoke_id]
        return Answered(packet.invoke_id, packet, response)

    def _notification(self, packet: AmsPacket) -> Event:
        try:
            stamps = DeviceNotification.decode(packet.payload).stamps
        except AdsCodecError as error:
            return BadFrame(Malformed.NOTIFICATION, f"from {packet.source}: {error}")
        return Notified(packet.target.port, packet.source, stamps)

    def _fail(self, invoke_id: int | None, kind: Malformed, detail: str) -> BadFrame:
        if invoke_id is not None and self._in_flight.pop(invoke_id, None):
            return BadFrame(kind, detail, invoke_id)
        return BadFrame(kind, detail)

    def _allocate(self) -> int:
        invoke_id = self._next_invoke_id
        while invoke_id in self._in_flight or invoke_id in self._forgotten:
            invoke_id = invoke_id % MAX_INVOKE_ID + 1
        self._next_invoke_id = invoke_id % MAX_INVOKE_ID + 1
        return invoke_id


def _max_data(request: AdsRequest) -> int | None:
    if isinstance(request, ReadRequest):
        return request.length
    if isinstance(request, ReadWriteRequest):
        return request.read_length
    return None


def _check_length(response: AdsResponse, max_data: int | None) -> None:
    """A Read or ReadWrite answer must not carry more than was asked for."""
    if (
        max_data is not None
        and isinstance(response, ReadResponse | ReadWriteResponse)
        and len(response.data) > max_data
    ):
        raise AdsCodecError(
            f"{len(response.data)} data bytes answer a request for {max_data}"
        )


__all__ = [
    "MAX_FRAME_SIZE",
    "Answered",
    "BadFrame",
    "Broken",
    "ClientSession",
    "Event",
    "Late",
    "Malformed",
    "Notified",
]
