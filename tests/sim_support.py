"""Test support for the simulator's I/O layer: a stand-in target and a raw client.

The stand-in for `SimTarget` lets the server's tests test the server.

It answers like a TwinCAT I/O server would, through the real codec:
ReadDeviceInfo and ReadState on port 300 and on the device port, Read and
Write of a 256-byte input image (0xF020) and output image (0xF030), AMS
error 0x6 for any other port, 0x702 for any other group. `tick()` counts the
u16 at input byte 0 up, so on-change notifications have something to see.
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

from fastcs_ethercat.ads.commands import (
    ReadDeviceInfoResponse,
    ReadRequest,
    ReadResponse,
    ReadStateResponse,
    WriteRequest,
    WriteResponse,
    decode_request,
    error_packet,
)
from fastcs_ethercat.ads.constants import (
    AdsReturnCode,
    AdsState,
    AmsCommand,
    IndexGroup,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import AmsPacket, FrameReassembler, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId

IO_SERVER_PORT: Final = 300
DEVICE_PORT: Final = 27905
IMAGE_SIZE: Final = 256

SYMBOLS: Final = {"Counter": (0, "<H"), "Value": (4, "<I"), "Flag": (8, "<B")}
"""Stand-in symbols: name -> (byte offset in the input image, struct format)."""


@dataclass
class StandInTarget:
    """Answers a handful of services of a TwinCAT I/O server."""

    system_net_id: AmsNetId = field(
        default_factory=lambda: AmsNetId.parse("10.20.30.40.1.1")
    )
    inputs: bytearray = field(default_factory=lambda: bytearray(IMAGE_SIZE))
    outputs: bytearray = field(default_factory=lambda: bytearray(IMAGE_SIZE))
    running: bool = True
    forced_error: tuple[int, int | None] | None = None
    calls: list[tuple[str, tuple[Any, ...]]] = field(default_factory=list)
    ticks: int = 0
    cycle_s: float = 0.01
    fail_with: Exception | None = None
    """If set, `handle` raises it (to test that the server survives)."""

    @property
    def device_net_id(self) -> AmsNetId:
        return self.system_net_id.with_octet(4, 2)

    @property
    def net_ids(self) -> frozenset[AmsNetId]:
        return frozenset({self.system_net_id, self.device_net_id})

    # -- the services ----------------------------------------------------------

    def handle(self, packet: AmsPacket) -> AmsPacket | None:
        if self.fail_with is not None:
            raise self.fail_with
        if packet.target.port not in (IO_SERVER_PORT, DEVICE_PORT):
            return packet.response(error_code=AdsReturnCode.TARGET_PORT_NOT_FOUND)
        request = decode_request(int(packet.command), packet.payload)
        group = getattr(request, "index_group", None)
        if self.forced_error is not None:
            code, only = self.forced_error
            if only is None or only == group:
                return error_packet(packet, code)
        match packet.command:
            case AmsCommand.READ_DEVICE_INFO:
                answer = ReadDeviceInfoResponse(
                    major=3, minor=1, build=2103, name="I/O Server"
                )
            case AmsCommand.READ_STATE:
                state = AdsState.RUN if self.running else AdsState.STOP
                answer = ReadStateResponse(ads_state=state)
            case AmsCommand.READ:
                assert isinstance(request, ReadRequest)
                result, data = self.read(
                    packet.target,
                    request.index_group,
                    request.index_offset,
                    request.length,
                )
                answer = ReadResponse(result, data)
            case AmsCommand.WRITE:
                assert isinstance(request, WriteRequest)
                answer = WriteResponse(self._write(request))
            case _:
                raise AdsCodecError(
                    "not served by the stand-in",
                    AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED,
                )
        return packet.response(payload=answer.encode())

    def _image(self, group: int) -> bytearray | None:
        if group == IndexGroup.IO_IMAGE_RW_INPUT_BYTES:
            return self.inputs
        if group == IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES:
            return self.outputs
        return None

    def read(
        self, address: AmsAddress, group: int, offset: int, length: int
    ) -> tuple[int, bytes]:
        if address.port not in (IO_SERVER_PORT, DEVICE_PORT):
            return AdsReturnCode.TARGET_PORT_NOT_FOUND, b""
        if self.forced_error is not None and self.forced_error[1] in (None, group):
            return self.forced_error[0], b""
        image = self._image(group)
        if image is None:
            return AdsReturnCode.DEVICE_INVALID_GROUP, b""
        if offset >= len(image):
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        return AdsReturnCode.NO_ERROR, bytes(image[offset : offset + length])

    def _write(self, request: WriteRequest) -> int:
        image = self._image(request.index_group)
        if image is None:
            return AdsReturnCode.DEVICE_INVALID_GROUP
        end = request.index_offset + len(request.data)
        if end > len(image):
            return AdsReturnCode.DEVICE_INVALID_SIZE
        image[request.index_offset : end] = request.data
        return AdsReturnCode.NO_ERROR

    def tick(self, now: float) -> None:
        self.ticks += 1
        counter = (struct.unpack_from("<H", self.inputs, 0)[0] + 1) & 0xFFFF
        struct.pack_into("<H", self.inputs, 0, counter)

    # -- control ------------------------------------------------------------------

    def get_symbol_value(self, name: str) -> Any:
        offset, fmt = SYMBOLS[name]
        return struct.unpack_from(fmt, self.inputs, offset)[0]

    def set_symbol_value(self, name: str, value: Any) -> None:
        offset, fmt = SYMBOLS[name]
        if not isinstance(value, int):
            raise TypeError(f"{name} takes an integer, got {value!r}")
        try:
            struct.pack_into(fmt, self.inputs, offset, value)
        except struct.error as error:
            raise ValueError(str(error)) from None

    def set_slave_state(
        self,
        address_or_name: int | str | None,
        state: int | str,
        device: int | None = None,
    ) -> None:
        self.calls.append(("set_slave_state", (address_or_name, state, device)))

    def set_link_lost(
        self, address_or_name: int | str | None, lost: bool, device: int | None = None
    ) -> None:
        self.calls.append(("set_link_lost", (address_or_name, lost, device)))

    def online_change(
        self, pdo_groups: Mapping[str, str] | None = None, removed: Sequence[str] = ()
    ) -> None:
        self.calls.append(("online_change", (pdo_groups, tuple(removed))))

    def set_run_state(self, running: bool) -> None:
        self.running = running
        self.calls.append(("set_run_state", (running,)))

    def force_error(self, code: int, group: int | None = None) -> None:
        self.forced_error = (code, group)
        self.calls.append(("force_error", (code, group)))

    def set_sum_commands(self, served: bool) -> None:
        self.calls.append(("set_sum_commands", (served,)))

    def fail_symbols(self, code: int, symbols: Sequence[str]) -> None:
        self.calls.append(("fail_symbols", (code, tuple(symbols))))

    def clear_faults(self) -> None:
        self.forced_error = None
        self.running = True
        self.calls.append(("clear_faults", ()))

    def describe(self) -> dict[str, Any]:
        return {"stand_in": True, "symbols": sorted(SYMBOLS)}


# -- a raw AMS/TCP client on the codec, for byte-level tests -----------------------

CLIENT: Final = AmsAddress(AmsNetId.parse("10.0.0.99.1.1"), 32_905)


def request(
    target: AmsAddress,
    command: int,
    payload: bytes = b"",
    invoke_id: int = 1,
    source: AmsAddress = CLIENT,
) -> AmsPacket:
    """A request packet from the test client."""
    return AmsPacket(
        target=target,
        source=source,
        command=command,
        invoke_id=invoke_id,
        payload=payload,
    )


class RawClient:
    """An asyncio AMS/TCP client that sends bytes and reads whole packets."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        self.reader = reader
        self.writer = writer
        self._reassembler = FrameReassembler()
        self._packets: list[AmsPacket] = []

    @classmethod
    async def connect(cls, port: int, host: str = "127.0.0.1") -> RawClient:
        reader, writer = await asyncio.open_connection(host, port)
        return cls(reader, writer)

    async def send(self, data: bytes | AmsPacket) -> None:
        if isinstance(data, AmsPacket):
            data = encode_packet(data)
        self.writer.write(data)
        await self.writer.drain()

    async def receive(self, timeout: float = 5.0) -> AmsPacket:
        """The next packet; raise TimeoutError if none comes in time."""
        async with asyncio.timeout(timeout):
            while not self._packets:
                data = await self.reader.read(65536)
                if not data:
                    raise ConnectionResetError("server closed the connection")
                self._packets += self._reassembler.feed(data)
        return self._packets.pop(0)

    async def call(self, packet: AmsPacket, timeout: float = 5.0) -> AmsPacket:
        """The answer to `packet`; notifications that come before it (already
        on their way) stay queued for `receive`."""
        await self.send(packet)
        notifications: list[AmsPacket] = []
        while True:
            answer = await self.receive(timeout)
            if answer.command != AmsCommand.DEVICE_NOTIFICATION:
                self._packets[:0] = notifications
                return answer
            notifications.append(answer)

    async def closed_by_server(self, timeout: float = 5.0) -> bool:
        """True once the server has closed the stream (reads return EOF)."""
        try:
            async with asyncio.timeout(timeout):
                while await self.reader.read(65536):
                    pass
        except TimeoutError:
            return False
        except ConnectionError:
            return True
        return True

    async def close(self) -> None:
        self.writer.close()
        with contextlib.suppress(ConnectionError):
            await self.writer.wait_closed()
