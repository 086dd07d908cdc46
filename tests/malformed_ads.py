"""A target that turns hostile: malformed AMS/TCP frames and a proxy that
answers with them on request.

`malformed_answers(request, n)` gives the bytes of one bad frame of kind
`KINDS[n % len(KINDS)]` for a request the client sent: too long and too
short lengths, truncated headers, wrong invoke ids, random bytes, huge length
fields, wrong commands, lying payloads, stray requests and notifications.

`HostileProxy` stands between a client and a real target (the simulator): in
good mode it forwards both ways untouched; in bad mode every request is
answered with a burst of malformed frames instead, and the target never sees
it. It runs on the loop it is started on (its own thread in `ProxyThread`).
"""

from __future__ import annotations

import asyncio
import dataclasses
import random
import struct
import threading
from collections import Counter
from collections.abc import Callable
from typing import Any, Final

from fastcs_ethercat.ads.commands import (
    DeviceNotification,
    NotificationSample,
    NotificationStamp,
    ReadResponse,
)
from fastcs_ethercat.ads.constants import AmsCommand, StateFlag
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.frames import AmsPacket, FrameReassembler, encode_packet

_TCP: Final = struct.Struct("<HI")


def _answer(request: AmsPacket, payload: bytes = b"", **changes: Any) -> AmsPacket:
    packet = AmsPacket(
        target=request.source,
        source=request.target,
        command=request.command,
        state_flags=request.state_flags | StateFlag.RESPONSE,
        invoke_id=request.invoke_id,
        payload=payload,
    )
    return dataclasses.replace(packet, **changes)


def _header(packet: AmsPacket) -> bytes:
    """The 32-byte AMS header of `packet` (no AMS/TCP header)."""
    return encode_packet(packet)[6:38]


def length_too_long(request: AmsPacket, rng: random.Random) -> bytes:
    """AMS/TCP length 1 KB past the AMS header's cbData 0, zero padding (the
    reply that crashed AdsLib)."""
    return _TCP.pack(0, 32 + 1024) + _header(_answer(request)) + bytes(1024)


def length_too_short(request: AmsPacket, rng: random.Random) -> bytes:
    """AMS/TCP length below the 32-byte AMS header."""
    size = rng.randrange(0, 32)
    return _TCP.pack(0, size) + rng.randbytes(size)


def truncated_header(request: AmsPacket, rng: random.Random) -> bytes:
    """An AMS/TCP header promising a frame, then only part of its header."""
    return _TCP.pack(0, 32 + 8) + _header(_answer(request))[: rng.randrange(1, 31)]


def wrong_invoke_id(request: AmsPacket, rng: random.Random) -> bytes:
    return encode_packet(
        _answer(
            request,
            ReadResponse(0, b"\0").encode(),
            invoke_id=(request.invoke_id + rng.randrange(1, 1 << 20)) & 0xFFFFFFFF,
        )
    )


def random_bytes(request: AmsPacket, rng: random.Random) -> bytes:
    return rng.randbytes(rng.randrange(1, 200))


def huge_length(request: AmsPacket, rng: random.Random) -> bytes:
    return _TCP.pack(0, rng.randrange(1 << 28, 1 << 32)) + _header(_answer(request))


def wrong_command(request: AmsPacket, rng: random.Random) -> bytes:
    return encode_packet(_answer(request, bytes(8), command=rng.choice((0, 11, 77))))


def lying_payload(request: AmsPacket, rng: random.Random) -> bytes:
    """A result and a length field that promises more data than follows."""
    return encode_packet(_answer(request, struct.pack("<II", 0, 5000) + b"abc"))


def data_length_mismatch(request: AmsPacket, rng: random.Random) -> bytes:
    """cbData larger than the frame holds (AMS/TCP length is right)."""
    packet = _answer(request, bytes(4))
    body = bytearray(encode_packet(packet)[6:])
    struct.pack_into("<I", body, 20, 4000)
    return _TCP.pack(0, len(body)) + bytes(body)


def stray_request(request: AmsPacket, rng: random.Random) -> bytes:
    """A request (no response flag) from the target to the client."""
    return encode_packet(
        AmsPacket(request.source, request.target, AmsCommand.READ, invoke_id=7)
    )


def garbage_notification(request: AmsPacket, rng: random.Random) -> bytes:
    return encode_packet(
        AmsPacket(
            request.source,
            request.target,
            AmsCommand.DEVICE_NOTIFICATION,
            payload=rng.randbytes(rng.randrange(0, 64)),
        )
    )


def unknown_notification(request: AmsPacket, rng: random.Random) -> bytes:
    """A well-formed notification for a handle nobody registered."""
    stamps = (NotificationStamp(1, (NotificationSample(0xBAD, b"\x01"),)),)
    return encode_packet(
        AmsPacket(
            request.source,
            request.target,
            AmsCommand.DEVICE_NOTIFICATION,
            payload=DeviceNotification(stamps).encode(),
        )
    )


KINDS: Final[tuple[Callable[[AmsPacket, random.Random], bytes], ...]] = (
    wrong_invoke_id,
    length_too_long,
    wrong_command,
    lying_payload,
    data_length_mismatch,
    stray_request,
    garbage_notification,
    unknown_notification,
    random_bytes,
    length_too_short,
    truncated_header,
    huge_length,
)
"""The first eight keep the AMS/TCP framing; the last four break it."""
FRAMING_KEPT: Final = 8


class HostileProxy:
    """A TCP proxy to `upstream` that answers with malformed frames while bad.

    In bad mode each request gets `burst` frames that keep the framing and
    then, every `break_every`-th request, one that breaks it (the client has
    to drop the connection and open another).
    """

    def __init__(
        self,
        upstream: tuple[str, int],
        *,
        burst: int = 20,
        break_every: int = 1,
        seed: int = 0,
    ) -> None:
        self.upstream = upstream
        self.burst = burst
        self.break_every = break_every
        self.bad = False
        self.sent: Counter[str] = Counter()
        self.connections = 0
        self._rng = random.Random(seed)
        self._requests = 0
        self._server: asyncio.Server | None = None
        self.port = 0

    @property
    def malformed_sent(self) -> int:
        return sum(self.sent.values())

    async def start(self) -> None:
        self._server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        self.port = self._server.sockets[0].getsockname()[1]

    async def stop(self) -> None:
        if self._server is not None:
            self._server.close()
            self._server = None

    async def _serve(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        self.connections += 1
        try:
            up_reader, up_writer = await asyncio.open_connection(*self.upstream)
        except OSError:
            writer.close()
            return
        back = asyncio.create_task(self._pipe(up_reader, writer))
        reassembler = FrameReassembler()
        try:
            while data := await reader.read(65536):
                try:
                    requests = reassembler.feed(data)
                except AdsCodecError:
                    break
                for request in requests:
                    if self.bad:
                        writer.write(self._malformed_for(request))
                    else:
                        up_writer.write(encode_packet(request))
                await writer.drain()
        except (ConnectionError, OSError):
            pass
        finally:
            back.cancel()
            up_writer.close()
            writer.close()

    @staticmethod
    async def _pipe(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while data := await reader.read(65536):
                writer.write(data)
                await writer.drain()
        except (ConnectionError, OSError):
            pass

    def _malformed_for(self, request: AmsPacket) -> bytes:
        self._requests += 1
        frames = []
        for _ in range(self.burst):
            kind = self._rng.choice(KINDS[:FRAMING_KEPT])
            self.sent[kind.__name__] += 1
            frames.append(kind(request, self._rng))
        if self._requests % self.break_every == 0:
            kind = self._rng.choice(KINDS[FRAMING_KEPT:])
            self.sent[kind.__name__] += 1
            frames.append(kind(request, self._rng))
        return b"".join(frames)


class ProxyThread:
    """A `HostileProxy` on its own loop in a daemon thread (for tests whose
    client is another process)."""

    def __init__(self, proxy: HostileProxy) -> None:
        self.proxy = proxy
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)

    def call(self, function: Callable[[], Any]) -> Any:
        async def run() -> Any:
            return function()

        return asyncio.run_coroutine_threadsafe(run(), self._loop).result(10)

    def __enter__(self) -> HostileProxy:
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self.proxy.start(), self._loop).result(10)
        return self.proxy

    def __exit__(self, *_: object) -> None:
        asyncio.run_coroutine_threadsafe(self.proxy.stop(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)
        self._loop.close()
