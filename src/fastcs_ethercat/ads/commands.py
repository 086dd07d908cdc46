"""ADS command payloads (the bytes after the AMS header), both directions.

One dataclass per request and per response, each with `encode()` and a
`decode(payload)` class method; `decode_request` / `decode_response` dispatch
on the AMS command id. Layouts: facts file section 2 and Beckhoff's ADS
specification. Every decoder raises only `AdsCodecError`, whose return code
is what a server answers (0x705 for a payload of the wrong size, 0x701 for an
unknown command).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, fields
from datetime import UTC, datetime, timedelta
from typing import Any, ClassVar, Final, Self, TypeVar, cast

from fastcs_ethercat.ads.constants import (
    NOTIFICATION_TIME_UNITS_PER_MS,
    AdsReturnCode,
    AmsCommand,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import AmsPacket
from fastcs_ethercat.ads.wire import (
    ByteReader,
    FixedRecord,
    decode_c_string,
    encode_text,
    pack,
)

DEVICE_NAME_SIZE: Final = 16
NOTIFICATION_RESERVED_SIZE: Final = 16

FILETIME_UNIX_EPOCH: Final = 116_444_736_000_000_000
"""1970-01-01T00:00:00Z as a FILETIME (100 ns ticks since 1601-01-01 UTC)."""
FILETIME_TICKS_PER_SECOND: Final = 10_000_000
_FILETIME_START: Final = datetime(1601, 1, 1, tzinfo=UTC)

_T = TypeVar("_T")


# -- time stamps ------------------------------------------------------------


def filetime_from_unix_ns(unix_ns: int) -> int:
    """FILETIME ticks for nanoseconds since the Unix epoch (time.time_ns())."""
    return FILETIME_UNIX_EPOCH + unix_ns // 100


def filetime_to_datetime(filetime: int) -> datetime:
    """Aware UTC datetime of FILETIME ticks (microsecond resolution)."""
    return _FILETIME_START + timedelta(microseconds=filetime // 10)


def notification_time_from_ms(milliseconds: float) -> int:
    """Max delay / cycle time field value (100 ns units) for milliseconds."""
    return round(milliseconds * NOTIFICATION_TIME_UNITS_PER_MS)


# -- shared pieces ----------------------------------------------------------


class _Payload:
    """Base of every command payload: knows its command id and direction."""

    command: ClassVar[AmsCommand]
    is_response: ClassVar[bool]

    def encode(self) -> bytes:
        raise NotImplementedError

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        raise NotImplementedError


class AdsRequest(_Payload):
    """A request payload."""

    is_response = False


class AdsResponse(_Payload):
    """A response payload; `result` is the service's ADS return code."""

    is_response = True
    result: int


class _Fixed(FixedRecord, _Payload):
    """A payload of fixed-size fields (a response may be its result alone)."""

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        reader = ByteReader(raw, cls.__name__)
        if (failed := _result_only(cls, reader)) is not None:
            return failed
        return cls.from_reader(reader)


class _Sized(_Payload):
    """Fixed fields, a data length (the layout's last field) and that many
    bytes of `data` (the dataclass's last field)."""

    layout: ClassVar[struct.Struct]

    def encode(self) -> bytes:
        *head, data = (getattr(self, f.name) for f in fields(cast(Any, self)))
        return pack(self.layout.format, *head, len(data)) + bytes(data)

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        reader = ByteReader(raw, cls.__name__)
        if (failed := _result_only(cls, reader)) is not None:
            return failed
        *head, length = cls.layout.unpack(reader.take(cls.layout.size))
        if length != reader.remaining:
            raise AdsCodecError(
                f"{reader.what}: length field says {length} data bytes, payload "
                f"has {reader.remaining}",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        return cast(Any, cls)(*head, reader.take(length))


def _result_only(cls: type[_T], reader: ByteReader) -> _T | None:
    """A failed response that is only its 4-byte result (some servers answer
    a failed Read, ReadWrite, ... so): the response with that result."""
    if not (issubclass(cls, AdsResponse) and reader.remaining == 4):
        return None
    layout = getattr(cls, "layout", None)
    if layout is not None and layout.size == 4:
        return None  # the result is the whole layout
    result = reader.u32()
    if result == AdsReturnCode.NO_ERROR:
        raise AdsCodecError(
            f"{reader.what}: a successful response needs more than its result",
            AdsReturnCode.DEVICE_INVALID_SIZE,
        )
    return cls(result=result)  # type: ignore[call-arg]


@dataclass(frozen=True, slots=True)
class _NoFields(_Fixed):
    """A request with no payload."""

    layout = struct.Struct("<")


@dataclass(frozen=True, slots=True)
class _ResultOnly(_Fixed, AdsResponse):
    """A response that is its result alone."""

    layout = struct.Struct("<I")
    result: int = AdsReturnCode.NO_ERROR


@dataclass(frozen=True, slots=True)
class _DataResponse(_Sized, AdsResponse):
    """A response that is its result and the data read (Read, ReadWrite)."""

    layout = struct.Struct("<II")
    result: int = AdsReturnCode.NO_ERROR
    data: bytes = b""


# -- ReadDeviceInfo (1) -----------------------------------------------------


@dataclass(frozen=True, slots=True)
class ReadDeviceInfoRequest(_NoFields, AdsRequest):
    command = AmsCommand.READ_DEVICE_INFO


@dataclass(frozen=True, slots=True)
class ReadDeviceInfoResponse(AdsResponse):
    """Name (max 15 characters + NUL) and version of an ADS device."""

    command = AmsCommand.READ_DEVICE_INFO
    result: int = AdsReturnCode.NO_ERROR
    major: int = 0
    minor: int = 0
    build: int = 0
    name: str = ""

    def encode(self) -> bytes:
        name = encode_text(self.name)
        if len(name) > DEVICE_NAME_SIZE:
            raise AdsCodecError(
                f"device name {self.name!r} is longer than {DEVICE_NAME_SIZE} bytes",
                AdsReturnCode.DEVICE_INVALID_DATA,
            )
        return pack("<IBBH", self.result, self.major, self.minor, self.build) + (
            name.ljust(DEVICE_NAME_SIZE, b"\0")
        )

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        reader = ByteReader(raw, "ReadDeviceInfo response")
        if (failed := _result_only(cls, reader)) is not None:
            return failed
        result = reader.u32()
        major, minor, build = reader.u8(), reader.u8(), reader.u16()
        name = decode_c_string(reader.take(DEVICE_NAME_SIZE))
        reader.expect_end()
        return cls(result, major, minor, build, name)


# -- Read (2), Write (3), ReadWrite (9) ----------------------------------------


@dataclass(frozen=True, slots=True)
class ReadRequest(_Fixed, AdsRequest):
    command = AmsCommand.READ
    layout = struct.Struct("<III")
    index_group: int
    index_offset: int
    length: int


@dataclass(frozen=True, slots=True)
class ReadResponse(_DataResponse):
    command = AmsCommand.READ


@dataclass(frozen=True, slots=True)
class WriteRequest(_Sized, AdsRequest):
    command = AmsCommand.WRITE
    layout = struct.Struct("<III")
    index_group: int
    index_offset: int
    data: bytes = b""


@dataclass(frozen=True, slots=True)
class WriteResponse(_ResultOnly):
    command = AmsCommand.WRITE


@dataclass(frozen=True, slots=True)
class ReadWriteRequest(_Sized, AdsRequest):
    command = AmsCommand.READ_WRITE
    layout = struct.Struct("<IIII")
    index_group: int
    index_offset: int
    read_length: int
    data: bytes = b""


@dataclass(frozen=True, slots=True)
class ReadWriteResponse(_DataResponse):
    command = AmsCommand.READ_WRITE


# -- ReadState (4), WriteControl (5) -----------------------------------------


@dataclass(frozen=True, slots=True)
class ReadStateRequest(_NoFields, AdsRequest):
    command = AmsCommand.READ_STATE


@dataclass(frozen=True, slots=True)
class ReadStateResponse(_Fixed, AdsResponse):
    command = AmsCommand.READ_STATE
    layout = struct.Struct("<IHH")
    result: int = AdsReturnCode.NO_ERROR
    ads_state: int = 0
    device_state: int = 0


@dataclass(frozen=True, slots=True)
class WriteControlRequest(_Sized, AdsRequest):
    command = AmsCommand.WRITE_CONTROL
    layout = struct.Struct("<HHI")
    ads_state: int
    device_state: int = 0
    data: bytes = b""


@dataclass(frozen=True, slots=True)
class WriteControlResponse(_ResultOnly):
    command = AmsCommand.WRITE_CONTROL


# -- Add / DeleteDeviceNotification (6, 7) ------------------------------------


@dataclass(frozen=True, slots=True)
class AddDeviceNotificationRequest(_Fixed, AdsRequest):
    """Max delay and cycle time are in 100 ns units (ms x 10 000)."""

    command = AmsCommand.ADD_DEVICE_NOTIFICATION
    layout = struct.Struct("<IIIIII")
    reserved = NOTIFICATION_RESERVED_SIZE
    index_group: int
    index_offset: int
    length: int
    transmission_mode: int
    max_delay: int = 0
    cycle_time: int = 0


@dataclass(frozen=True, slots=True)
class AddDeviceNotificationResponse(_Fixed, AdsResponse):
    command = AmsCommand.ADD_DEVICE_NOTIFICATION
    layout = struct.Struct("<II")
    result: int = AdsReturnCode.NO_ERROR
    handle: int = 0


@dataclass(frozen=True, slots=True)
class DeleteDeviceNotificationRequest(_Fixed, AdsRequest):
    command = AmsCommand.DELETE_DEVICE_NOTIFICATION
    layout = struct.Struct("<I")
    handle: int


@dataclass(frozen=True, slots=True)
class DeleteDeviceNotificationResponse(_ResultOnly):
    command = AmsCommand.DELETE_DEVICE_NOTIFICATION


# -- DeviceNotification (8, server -> client, never answered) ---------------


@dataclass(frozen=True, slots=True)
class NotificationSample:
    """One notified value: the handle AddDeviceNotification returned + data."""

    handle: int
    data: bytes


@dataclass(frozen=True, slots=True)
class NotificationStamp:
    """Samples sharing one FILETIME time stamp (100 ns since 1601, UTC)."""

    timestamp: int
    samples: tuple[NotificationSample, ...] = ()


@dataclass(frozen=True, slots=True)
class DeviceNotification(AdsRequest):
    """The notification stream: length u32 (bytes after this field), stamp
    count u32, then per stamp FILETIME u64, sample count u32, and per sample
    handle u32, size u32, data."""

    command = AmsCommand.DEVICE_NOTIFICATION
    stamps: tuple[NotificationStamp, ...] = field(default=())

    def encode(self) -> bytes:
        parts = [pack("<I", len(self.stamps))]
        for stamp in self.stamps:
            parts.append(pack("<QI", stamp.timestamp, len(stamp.samples)))
            for sample in stamp.samples:
                parts.append(pack("<II", sample.handle, len(sample.data)))
                parts.append(bytes(sample.data))
        body = b"".join(parts)
        return pack("<I", len(body)) + body

    @classmethod
    def decode(cls, raw: bytes | bytearray | memoryview) -> Self:
        reader = ByteReader(raw, "DeviceNotification")
        length = reader.u32()
        if length != reader.remaining:
            raise AdsCodecError(
                f"DeviceNotification: length field says {length} bytes follow, "
                f"payload has {reader.remaining}",
                AdsReturnCode.DEVICE_INVALID_SIZE,
            )
        stamp_count = reader.u32()
        stamps: list[NotificationStamp] = []
        for _ in range(stamp_count):
            timestamp, sample_count = reader.u64(), reader.u32()
            samples: list[NotificationSample] = []
            for _ in range(sample_count):
                handle, size = reader.u32(), reader.u32()
                samples.append(NotificationSample(handle, reader.take(size)))
            stamps.append(NotificationStamp(timestamp, tuple(samples)))
        reader.expect_end()
        return cls(tuple(stamps))


# -- dispatch ---------------------------------------------------------------

REQUEST_TYPES: Final[dict[AmsCommand, type[AdsRequest]]] = {
    cls.command: cls
    for cls in (
        ReadDeviceInfoRequest,
        ReadRequest,
        WriteRequest,
        ReadStateRequest,
        WriteControlRequest,
        AddDeviceNotificationRequest,
        DeleteDeviceNotificationRequest,
        DeviceNotification,
        ReadWriteRequest,
    )
}

RESPONSE_TYPES: Final[dict[AmsCommand, type[AdsResponse]]] = {
    cls.command: cls
    for cls in (
        ReadDeviceInfoResponse,
        ReadResponse,
        WriteResponse,
        ReadStateResponse,
        WriteControlResponse,
        AddDeviceNotificationResponse,
        DeleteDeviceNotificationResponse,
        ReadWriteResponse,
    )
}


def _lookup(table: dict[AmsCommand, type[_T]], command_id: int, what: str) -> type[_T]:
    try:
        return table[AmsCommand(command_id)]
    except (ValueError, KeyError):
        raise AdsCodecError(
            f"no {what} for AMS command id {command_id}",
            AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED,
        ) from None


def decode_request(
    command_id: int, payload: bytes | bytearray | memoryview
) -> AdsRequest:
    """Decode a request payload by command id (0x701 for unknown commands)."""
    return _lookup(REQUEST_TYPES, command_id, "request").decode(payload)


def decode_response(
    command_id: int, payload: bytes | bytearray | memoryview
) -> AdsResponse:
    """Decode a response payload by command id (0x701 for unknown commands;
    DeviceNotification has no response)."""
    return _lookup(RESPONSE_TYPES, command_id, "response").decode(payload)


def error_response(command_id: int, result: int) -> AdsResponse:
    """The response a server sends when the service failed with `result`.

    The full layout with zeroed fields (e.g. Read: result, length 0); AdsLib
    reads the result first and stops on an error, so the rest is never used.
    Raises 0x701 for commands without a response.
    """
    return _lookup(RESPONSE_TYPES, command_id, "response")(result=result)  # type: ignore[call-arg]


def error_packet(packet: AmsPacket, code: int) -> AmsPacket:
    """The answer to request `packet` failing with `code`: in the result field
    of its command's response, or in the AMS header's error code for a
    command without one."""
    try:
        payload = error_response(int(packet.command), code).encode()
    except AdsCodecError:
        return packet.response(error_code=code)
    return packet.response(payload=payload)
