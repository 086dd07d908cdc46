"""AMS/TCP framing: the 6-byte AMS/TCP header, the 32-byte AMS header, and a
reassembler that turns a TCP byte stream into whole packets.

Layout (facts file section 1, little-endian):

    AMS/TCP header  reserved u16 = 0, length u32 (= 32 + data length)
    AMS header      target NetId[6], target port u16, source NetId[6],
                    source port u16, command id u16, state flags u16,
                    data length u32, error code u32, invoke id u32
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Final

from fastcs_ethercat.ads.constants import (
    AMS_HEADER_SIZE,
    AMS_TCP_HEADER_SIZE,
    REQUEST_FLAGS,
    AdsReturnCode,
    AmsCommand,
    StateFlag,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.wire import enum_or_int, pack

_TCP_HEADER: Final = struct.Struct("<HI")
_AMS_HEADER: Final = struct.Struct("<6sH6sHHHIII")

DEFAULT_MAX_FRAME_SIZE: Final = 16 * 1024 * 1024
"""Largest AMS/TCP length a reassembler accepts unless told otherwise."""


class FrameTooLargeError(AdsCodecError):
    """An AMS/TCP length beyond the reassembler's maximum frame size."""


@dataclass(frozen=True, slots=True)
class AmsPacket:
    """One AMS packet: routing header fields plus the command's payload."""

    target: AmsAddress
    source: AmsAddress
    command: AmsCommand | int
    state_flags: int = REQUEST_FLAGS
    error_code: int = AdsReturnCode.NO_ERROR
    invoke_id: int = 0
    payload: bytes = field(default=b"", repr=False)

    @property
    def is_response(self) -> bool:
        return bool(self.state_flags & StateFlag.RESPONSE)

    def response(
        self,
        payload: bytes = b"",
        error_code: int = AdsReturnCode.NO_ERROR,
    ) -> AmsPacket:
        """The response to this request: addresses swapped, same command and
        invoke id, response bit set."""
        return AmsPacket(
            target=self.source,
            source=self.target,
            command=self.command,
            state_flags=self.state_flags | StateFlag.RESPONSE,
            error_code=error_code,
            invoke_id=self.invoke_id,
            payload=payload,
        )


def encode_ams_header(packet: AmsPacket) -> bytes:
    """The 32-byte AMS header of `packet` (data length from its payload)."""
    return pack(
        _AMS_HEADER,
        packet.target.netid.to_bytes(),
        packet.target.port,
        packet.source.netid.to_bytes(),
        packet.source.port,
        int(packet.command),
        int(packet.state_flags),
        len(packet.payload),
        int(packet.error_code),
        int(packet.invoke_id),
        what="AMS header field",
    )


def encode_packet(packet: AmsPacket) -> bytes:
    """A whole AMS/TCP frame: 6-byte AMS/TCP header, AMS header, payload."""
    header = encode_ams_header(packet)
    length = AMS_HEADER_SIZE + len(packet.payload)
    return _TCP_HEADER.pack(0, length) + header + packet.payload


def decode_ams(data: bytes | bytearray | memoryview) -> AmsPacket:
    """Decode an AMS header plus exactly its data length of payload."""
    if len(data) < AMS_HEADER_SIZE:
        raise AdsCodecError(
            f"AMS header needs {AMS_HEADER_SIZE} bytes, got {len(data)}",
            AdsReturnCode.INVALID_AMS_LENGTH,
        )
    (
        target_netid,
        target_port,
        source_netid,
        source_port,
        command_id,
        state_flags,
        data_length,
        error_code,
        invoke_id,
    ) = _AMS_HEADER.unpack_from(data)
    payload = bytes(data[AMS_HEADER_SIZE:])
    if data_length != len(payload):
        raise AdsCodecError(
            f"AMS header says {data_length} data bytes, frame carries {len(payload)}",
            AdsReturnCode.INVALID_AMS_LENGTH,
        )
    return AmsPacket(
        target=AmsAddress(AmsNetId.from_bytes(target_netid), target_port),
        source=AmsAddress(AmsNetId.from_bytes(source_netid), source_port),
        command=enum_or_int(AmsCommand, command_id),
        state_flags=state_flags,
        error_code=error_code,
        invoke_id=invoke_id,
        payload=payload,
    )


def decode_tcp_header(header: bytes | bytearray | memoryview) -> int:
    """Validate a 6-byte AMS/TCP header and return its length field."""
    if len(header) != AMS_TCP_HEADER_SIZE:
        raise AdsCodecError(
            f"AMS/TCP header is {AMS_TCP_HEADER_SIZE} bytes, got {len(header)}",
            AdsReturnCode.INVALID_AMS_LENGTH,
        )
    reserved, length = _TCP_HEADER.unpack(bytes(header))
    if reserved != 0:
        raise AdsCodecError(
            f"AMS/TCP reserved field is 0x{reserved:04X}, expected 0 "
            "(router-internal commands are not ADS)",
            AdsReturnCode.UNKNOWN_AMS_COMMAND,
        )
    if length < AMS_HEADER_SIZE:
        raise AdsCodecError(
            f"AMS/TCP length {length} is shorter than the {AMS_HEADER_SIZE}-byte "
            "AMS header",
            AdsReturnCode.INVALID_AMS_LENGTH,
        )
    return length


class FrameReassembler:
    """Turns TCP reads into whole AMS packets (sans-I/O state machine).

    Feed whatever `recv` returned; get back every packet completed by it.
    Split headers, split bodies and several frames in one read all work. A
    malformed or oversized header raises `AdsCodecError`; the stream has then
    lost its framing, so the reassembler stays broken and the caller should
    close the connection.
    """

    __slots__ = ("_broken", "_buffer", "max_frame_size")

    def __init__(self, max_frame_size: int = DEFAULT_MAX_FRAME_SIZE) -> None:
        self.max_frame_size = max_frame_size
        """Largest accepted AMS/TCP length (AMS header + data), in bytes."""
        self._buffer = bytearray()
        self._broken: AdsCodecError | None = None

    @property
    def buffered(self) -> int:
        """Bytes received but not yet part of a complete frame."""
        return len(self._buffer)

    @property
    def broken(self) -> AdsCodecError | None:
        """Why the stream lost its framing, once it has."""
        return self._broken

    def feed(self, data: bytes | bytearray | memoryview) -> list[AmsPacket]:
        """Add received bytes; return the packets they complete, in order.

        Raises `AdsCodecError` when the framing breaks or a frame's AMS
        header disagrees with its AMS/TCP length (a server closes such a
        client); `split` leaves the AMS header to the caller.
        """
        frames = self.split(data)
        if self._broken is not None:
            raise self._broken
        try:
            return [decode_ams(frame) for frame in frames]
        except AdsCodecError as error:
            self._broken = error
            raise

    def split(self, data: bytes | bytearray | memoryview) -> list[bytes]:
        """Add received bytes; return the AMS bodies (AMS header + data) of
        every frame they complete, in order, each checked only against its
        AMS/TCP header (reserved field, length bounds).

        Where the framing breaks, the frames before the break are returned
        and `broken` tells why; the stream is then lost (a further call
        raises `AdsCodecError`).
        """
        if self._broken is not None:
            raise AdsCodecError(
                f"stream already broken: {self._broken}", self._broken.return_code
            )
        self._buffer += data
        frames: list[bytes] = []
        start = 0
        buffer = self._buffer
        try:
            while len(buffer) - start >= AMS_TCP_HEADER_SIZE:
                header_end = start + AMS_TCP_HEADER_SIZE
                length = decode_tcp_header(buffer[start:header_end])
                if length > self.max_frame_size:
                    raise FrameTooLargeError(
                        f"AMS/TCP frame of {length} bytes exceeds the limit of "
                        f"{self.max_frame_size}",
                        AdsReturnCode.INVALID_AMS_LENGTH,
                    )
                frame_end = header_end + length
                if len(buffer) < frame_end:
                    break
                frames.append(bytes(buffer[header_end:frame_end]))
                start = frame_end
        except AdsCodecError as error:
            self._broken = error
            buffer.clear()
            return frames
        del buffer[:start]
        return frames


def header_invoke_id(body: bytes | bytearray | memoryview) -> int | None:
    """The invoke id of an AMS body whose header is whole, else None (read
    even when the rest of the frame is malformed, to fail its request)."""
    if len(body) < AMS_HEADER_SIZE:
        return None
    return int(_AMS_HEADER.unpack_from(body)[-1])
