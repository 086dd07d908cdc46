"""The asyncio ADS client against the simulator's AMS/TCP server.

The server (`sim.server.AmsServer`) and the UDP responder (`sim.udp`) are the
simulator's own; only the target behind them is a small one of this file: a
few memory areas, a symbol and a data-type table encoded by the codec, 0xF009
info-by-name (alone and in 0xF082 sums) and 0xF080 sum reads. The simulator
itself is checked against pyads (Beckhoff's AdsLib) elsewhere, so the two
ends do not just agree with each other.
"""

from __future__ import annotations

import asyncio
import logging
import struct
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, Final, TypeVar

import pytest
from pydantic import SecretStr

from fastcs_ethercat.ads.client import (
    AdsClient,
    AdsConnectionError,
    AdsError,
    AdsProtocolError,
    AdsRouteError,
    AdsTimeoutError,
    Notification,
    add_route,
    discover_net_id,
)
from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationResponse,
    DeviceNotification,
    NotificationSample,
    NotificationStamp,
    ReadDeviceInfoResponse,
    ReadRequest,
    ReadResponse,
    ReadStateResponse,
    ReadWriteRequest,
    ReadWriteResponse,
    WriteRequest,
    WriteResponse,
    decode_request,
)
from fastcs_ethercat.ads.connection import AmsTcpConnection
from fastcs_ethercat.ads.constants import (
    AdsDataType,
    AdsReturnCode,
    AdsState,
    AmsCommand,
    IndexGroup,
)
from fastcs_ethercat.ads.datatypes import AdsDataTypeEntry, encode_data_type_table
from fastcs_ethercat.ads.frames import AmsPacket, FrameReassembler, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.sums import (
    SumReadItem,
    SumReadRequest,
    SumReadResponse,
    SumReadWriteRequest,
    SumReadWriteResponse,
)
from fastcs_ethercat.ads.symbols import (
    AdsSymbolEntry,
    SymbolUploadInfo2,
    encode_symbol_table,
)
from fastcs_ethercat.ioc.config import RouteConfig
from fastcs_ethercat.sim.server import AmsServer
from fastcs_ethercat.sim.udp import UdpResponder
from tests.ads_codec import filetime_to_unix_ns

NET_ID: Final = AmsNetId.parse("192.0.2.17.1.1")
"""TEST-NET NetId, so no other test's AdsLib route can clash with ours."""
OTHER_NET_ID: Final = AmsNetId.parse("192.0.2.18.1.1")
DEVICE_PORT: Final = 27905
INPUTS: Final = int(IndexGroup.IO_IMAGE_RW_INPUT_BYTES)
OUTPUTS: Final = int(IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES)
UNKNOWN_GROUP: Final = 0x1234
ROUTE_USER: Final = "Administrator"
ROUTE_PASSWORD: Final = "s3cret-Pa55"
_T = TypeVar("_T")

SYMBOLS: Final = [
    AdsSymbolEntry(
        "Term 5 (EL3104).AI Standard Channel 1",
        INPUTS,
        0,
        4,
        AdsDataType.BIGTYPE,
        "AI Standard Channel 1_TYPE",
    ),
    AdsSymbolEntry(
        "Term 5 (EL3104).AI Standard Channel 1.Value",
        INPUTS,
        2,
        2,
        AdsDataType.INT16,
        "INT",
    ),
    AdsSymbolEntry(
        "Term 6 (EL3602).AI Inputs Channel 1.Value",
        INPUTS,
        8,
        4,
        AdsDataType.INT32,
        "DINT",
    ),
]
DATA_TYPES: Final = [
    AdsDataTypeEntry(
        "AI Standard Channel 1_TYPE",
        "",
        4,
        sub_items=(
            AdsDataTypeEntry("Status", "UINT", 2, AdsDataType.UINT16, offset=0),
            AdsDataTypeEntry("Value", "INT", 2, AdsDataType.INT16, offset=2),
        ),
    )
]


class ClientTestTarget:
    """Answers what the client needs, through the codec."""

    def __init__(self) -> None:
        self.memory = {INPUTS: bytearray(4096), OUTPUTS: bytearray(256)}
        self.sum_read_counts: list[int] = []
        self.symbols_raw = encode_symbol_table(SYMBOLS)
        self.types_raw = encode_data_type_table(DATA_TYPES)
        self.by_name = {entry.name: entry for entry in SYMBOLS}

    @property
    def net_ids(self) -> frozenset[AmsNetId]:
        return frozenset({NET_ID})

    def read(
        self, address: AmsAddress, group: int, offset: int, length: int
    ) -> tuple[int, bytes]:
        area = self.memory.get(group)
        if area is None:
            return AdsReturnCode.DEVICE_INVALID_GROUP, b""
        if offset >= len(area):
            return AdsReturnCode.DEVICE_INVALID_OFFSET, b""
        return AdsReturnCode.NO_ERROR, bytes(area[offset : offset + length])

    def handle(self, packet: AmsPacket) -> AmsPacket | None:
        if packet.target.port != DEVICE_PORT:
            return packet.response(error_code=AdsReturnCode.TARGET_PORT_NOT_FOUND)
        request = decode_request(int(packet.command), packet.payload)
        match request:
            case ReadRequest():
                answer = ReadResponse(*self._read(request))
            case WriteRequest():
                answer = WriteResponse(self._write(request))
            case ReadWriteRequest():
                answer = self._read_write(request)
            case _ if packet.command == AmsCommand.READ_STATE:
                answer = ReadStateResponse(ads_state=AdsState.RUN, device_state=1)
            case _ if packet.command == AmsCommand.READ_DEVICE_INFO:
                answer = ReadDeviceInfoResponse(
                    major=3, minor=1, build=2103, name="I/O Server"
                )
            case _:
                return None
        return packet.response(payload=answer.encode())

    def _read(self, request: ReadRequest) -> tuple[int, bytes]:
        tables: dict[int, bytes] = {
            IndexGroup.SYM_UPLOAD_INFO_2: SymbolUploadInfo2(
                len(SYMBOLS),
                len(self.symbols_raw),
                len(DATA_TYPES),
                len(self.types_raw),
            ).encode(),
            IndexGroup.SYM_UPLOAD: self.symbols_raw,
            IndexGroup.SYM_DT_UPLOAD: self.types_raw,
        }
        if request.index_group in tables:
            return AdsReturnCode.NO_ERROR, tables[request.index_group][: request.length]
        return self.read(
            NET_ID_ADDRESS, request.index_group, request.index_offset, request.length
        )

    def _write(self, request: WriteRequest) -> int:
        area = self.memory.get(request.index_group)
        if area is None:
            return AdsReturnCode.DEVICE_INVALID_GROUP
        end = request.index_offset + len(request.data)
        if end > len(area):
            return AdsReturnCode.DEVICE_INVALID_SIZE
        area[request.index_offset : end] = request.data
        return AdsReturnCode.NO_ERROR

    def _read_write(self, request: ReadWriteRequest) -> ReadWriteResponse:
        if request.index_group == IndexGroup.SUMUP_READ_WRITE:
            items = SumReadWriteRequest.decode(request.data, request.index_offset).items
            answers = [
                self._read_write(
                    ReadWriteRequest(
                        i.index_group, i.index_offset, i.read_length, i.data
                    )
                )
                for i in items
            ]
            data = SumReadWriteResponse(
                tuple(a.result for a in answers), tuple(a.data for a in answers)
            ).encode()
            return ReadWriteResponse(AdsReturnCode.NO_ERROR, data)
        if request.index_group == IndexGroup.SUMUP_READ:
            items = SumReadRequest.decode(request.data, request.index_offset).items
            self.sum_read_counts.append(len(items))
            outcomes = [
                self.read(NET_ID_ADDRESS, i.index_group, i.index_offset, i.length)
                for i in items
            ]
            data = SumReadResponse.for_items(items, outcomes).encode()
            return ReadWriteResponse(AdsReturnCode.NO_ERROR, data)
        if request.index_group == IndexGroup.SYM_INFO_BY_NAME_EX:
            entry = self.by_name.get(request.data.rstrip(b"\0").decode())
            if entry is None:
                return ReadWriteResponse(AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND)
            return ReadWriteResponse(AdsReturnCode.NO_ERROR, entry.encode())
        written = self._write(
            WriteRequest(request.index_group, request.index_offset, request.data)
        )
        if written != AdsReturnCode.NO_ERROR:
            return ReadWriteResponse(written)
        result, data = self.read(
            NET_ID_ADDRESS,
            request.index_group,
            request.index_offset,
            request.read_length,
        )
        return ReadWriteResponse(result, data)


NET_ID_ADDRESS: Final = AmsAddress(NET_ID, DEVICE_PORT)


class ServerThread:
    """The simulator's AMS server and UDP responder on a loop of their own."""

    def __init__(self, target: ClientTestTarget) -> None:
        self.target = target
        self.server = AmsServer(target)
        self.udp = UdpResponder(
            NET_ID, host_name="fake-plc", credentials=(ROUTE_USER, ROUTE_PASSWORD)
        )
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._ticker: asyncio.Task[None] | None = None

    def call(self, function: Callable[[], _T]) -> _T:
        async def run() -> _T:
            return function()

        return asyncio.run_coroutine_threadsafe(run(), self._loop).result(10)

    def start(self) -> None:
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self._start(), self._loop).result(10)

    async def _start(self) -> None:
        await self.server.start("127.0.0.1", 0)
        await self.udp.start("127.0.0.1", 0)
        self._ticker = asyncio.get_running_loop().create_task(self._tick())

    async def _tick(self) -> None:
        while True:
            self.server.tick()
            await asyncio.sleep(0.005)

    def stop(self) -> None:
        async def stop() -> None:
            if self._ticker is not None:
                self._ticker.cancel()
            self.udp.close()
            await self.server.close()

        asyncio.run_coroutine_threadsafe(stop(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)
        self._loop.close()


@pytest.fixture(scope="module")
def server() -> Iterator[ServerThread]:
    thread = ServerThread(ClientTestTarget())
    thread.start()
    yield thread
    thread.stop()


@pytest.fixture
async def client(server: ServerThread) -> Any:
    async with AdsClient(
        "127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=server.server.port, timeout_ms=2000
    ) as ads:
        yield ads


async def test_read_state_and_device_info(client: AdsClient) -> None:
    status = await client.read_state()
    info = await client.read_device_info()

    assert status.ads_state is AdsState.RUN
    assert status.device_state == 1
    assert (info.name, info.version) == ("I/O Server", "3.1.2103")


async def test_raw_write_read_and_read_write(client: AdsClient) -> None:
    await client.write(OUTPUTS, 10, b"\x01\x02\x03")
    assert await client.read(OUTPUTS, 9, 5) == b"\x00\x01\x02\x03\x00"

    answer = await client.read_write(OUTPUTS, 20, 4, b"\xaa\xbb")

    assert answer == b"\xaa\xbb\x00\x00"
    assert await client.read(OUTPUTS, 20, 2) == b"\xaa\xbb"


async def test_errors_carry_the_ads_code(
    client: AdsClient, server: ServerThread
) -> None:
    with pytest.raises(AdsError) as unknown_group:
        await client.read(UNKNOWN_GROUP, 0, 4)
    with pytest.raises(AdsProtocolError) as short_answer:
        await client.read(OUTPUTS, 250, 16)  # only 6 bytes are there

    assert unknown_group.value.code == AdsReturnCode.DEVICE_INVALID_GROUP
    assert type(unknown_group.value) is AdsError
    assert "DEVICE_INVALID_GROUP" in str(unknown_group.value)
    assert short_answer.value.code == AdsReturnCode.DEVICE_INVALID_SIZE

    async with AdsClient(
        "127.0.0.1", NET_ID, 999, tcp_port=server.server.port, timeout_ms=2000
    ) as wrong_port:
        with pytest.raises(AdsConnectionError) as no_port:
            await wrong_port.read_state()
    async with AdsClient(
        "127.0.0.1", OTHER_NET_ID, DEVICE_PORT, tcp_port=server.server.port
    ) as wrong_machine:
        with pytest.raises(AdsConnectionError) as no_machine:
            await wrong_machine.read_state()

    assert no_port.value.code == AdsReturnCode.TARGET_PORT_NOT_FOUND
    assert no_machine.value.code == AdsReturnCode.TARGET_MACHINE_NOT_FOUND


async def test_clients_share_one_connection_with_many_requests_in_flight(
    server: ServerThread,
) -> None:
    """Every AMS address behind one router travels on one TCP connection,
    and requests overlap instead of waiting for each other."""
    memory = server.target.memory[INPUTS]
    for index in range(100):
        struct.pack_into("<H", memory, 2 * index, 1000 + index)
    accepted = server.call(lambda: server.server.counters.connections_accepted)
    connection = AmsTcpConnection("127.0.0.1", server.server.port)
    device = AdsClient(
        "127.0.0.1",
        NET_ID,
        DEVICE_PORT,
        tcp_port=server.server.port,
        connection=connection,
    )
    other_port = AdsClient(
        "127.0.0.1", NET_ID, 999, tcp_port=server.server.port, connection=connection
    )
    async with device, other_port:
        values = await asyncio.gather(
            *(device.read(INPUTS, 2 * index, 2) for index in range(100))
        )
        with pytest.raises(AdsConnectionError):
            await other_port.read_state()
        peak = connection.stats.requests

    assert [struct.unpack("<H", v)[0] for v in values] == list(range(1000, 1100))
    assert peak == 101
    assert server.call(lambda: server.server.counters.connections_accepted) == (
        accepted + 1
    )


async def test_timeout_is_typed_and_the_loop_keeps_running(
    server: ServerThread,
) -> None:
    gaps: list[float] = []

    async def ticker(stop: asyncio.Event) -> None:
        last = time.perf_counter()
        while not stop.is_set():
            await asyncio.sleep(0.01)
            now = time.perf_counter()
            gaps.append(now - last)
            last = now

    async with AdsClient(
        "127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=server.server.port, timeout_ms=400
    ) as ads:
        stop = asyncio.Event()
        ticking = asyncio.create_task(ticker(stop))
        server.call(lambda: server.server.stall(1.0))
        started = time.perf_counter()
        with pytest.raises(AdsTimeoutError) as timed_out:
            await ads.read_state()
        waited = time.perf_counter() - started
        stop.set()
        await ticking
        server.call(server.server.end_stall)

    assert timed_out.value.code == AdsReturnCode.CLIENT_SYNC_TIMEOUT
    assert 0.3 < waited < 1.0
    assert len(gaps) > 20
    assert max(gaps) < 0.2, "the event loop was blocked while the request waited"


async def test_sum_read_splits_at_500_and_keeps_item_errors(
    client: AdsClient, server: ServerThread
) -> None:
    memory = server.target.memory[INPUTS]
    for index in range(1203):
        struct.pack_into("<H", memory, 2 * index, index)
    items = [SumReadItem(INPUTS, 2 * index, 2) for index in range(1203)]
    items[700] = SumReadItem(UNKNOWN_GROUP, 0, 2)
    server.target.sum_read_counts.clear()

    answers = await client.sum_read(items)
    outcomes = await client.sum_read_items(items)

    assert server.target.sum_read_counts == [500, 500, 203, 500, 500, 203]
    assert [len(answer) for answer in answers] == [500 * 6, 500 * 6, 203 * 6]
    assert outcomes[700] == (AdsReturnCode.DEVICE_INVALID_GROUP, b"\0\0")
    assert all(
        outcome == (0, struct.pack("<H", index))
        for index, outcome in enumerate(outcomes)
        if index != 700
    )


async def test_read_list_by_name_gives_values_and_errors_by_name(
    client: AdsClient, server: ServerThread
) -> None:
    memory = server.target.memory[INPUTS]
    struct.pack_into("<h", memory, 2, -1234)
    struct.pack_into("<i", memory, 8, 7_000_000)

    values = await client.read_list_by_name(
        [
            "Term 5 (EL3104).AI Standard Channel 1.Value",
            "Term 6 (EL3602).AI Inputs Channel 1.Value",
            "Term 7 (EL9999).Nothing",
        ]
    )

    assert values["Term 5 (EL3104).AI Standard Channel 1.Value"] == -1234
    assert values["Term 6 (EL3602).AI Inputs Channel 1.Value"] == 7_000_000
    assert "DEVICE_SYMBOL_NOT_FOUND" in values["Term 7 (EL9999).Nothing"]


async def test_symbol_upload_is_decoded_by_the_codec(client: AdsClient) -> None:
    tables = await client.upload_symbols()

    def symbol_fields(entry: AdsSymbolEntry) -> tuple[Any, ...]:
        return (
            entry.name,
            entry.index_group,
            entry.index_offset,
            entry.size,
            entry.data_type,
            entry.type_name,
        )

    def member_fields(entry: AdsDataTypeEntry) -> list[tuple[Any, ...]]:
        return [(m.name, m.type_name, m.offset, m.size) for m in entry.sub_items]

    assert [symbol_fields(s) for s in tables.symbols] == [
        symbol_fields(s) for s in SYMBOLS
    ]
    assert [(t.name, t.size) for t in tables.data_types] == [
        ("AI Standard Channel 1_TYPE", 4)
    ]
    assert member_fields(tables.data_types[0]) == member_fields(DATA_TYPES[0])
    assert tables.info.symbol_count == len(SYMBOLS)
    assert tables.raw_symbols == encode_symbol_table(SYMBOLS)


async def test_notifications_hop_to_the_loop_thread(
    client: AdsClient, server: ServerThread
) -> None:
    loop_thread = threading.get_ident()
    received: list[tuple[Notification, int]] = []
    arrived = asyncio.Event()

    def on_sample(sample: Notification) -> None:
        received.append((sample, threading.get_ident()))
        arrived.set()

    async def next_sample() -> Notification:
        await asyncio.wait_for(arrived.wait(), 5)
        arrived.clear()
        return received[-1][0]

    handle = await client.add_notification(INPUTS, 3000, 4, on_sample, cycle_time_ms=5)
    first = await next_sample()
    await client.write(INPUTS, 3000, b"\x11\x22\x33\x44")
    second = await next_sample()
    await client.delete_notification(handle)
    count = len(received)
    await client.write(INPUTS, 3000, b"\x55\x55\x55\x55")
    await asyncio.sleep(0.2)

    assert first.data == b"\0\0\0\0"
    assert second.data == b"\x11\x22\x33\x44"
    assert second.handle == handle.notification
    assert abs(filetime_to_unix_ns(second.timestamp) / 1e9 - time.time()) < 5
    assert {thread for _, thread in received} == {loop_thread}
    assert len(received) == count, "a deleted notification still arrived"


async def test_closed_client_raises_a_typed_error(server: ServerThread) -> None:
    ads = AdsClient("127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=server.server.port)
    await ads.open()
    await ads.close()
    await ads.close()

    with pytest.raises(AdsConnectionError) as closed:
        await ads.read_state()

    assert closed.value.code == AdsReturnCode.CLIENT_PORT_NOT_OPEN


async def test_close_fails_requests_in_flight_at_once(
    server: ServerThread,
) -> None:
    """Closing a client of a target that stopped answering does not wait for
    its requests to time out."""
    ads = AdsClient(
        "127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=server.server.port, timeout_ms=4000
    )
    await ads.open()
    server.call(lambda: server.server.stall(10.0))
    try:
        in_flight = [asyncio.create_task(ads.read_state()) for _ in range(10)]
        await asyncio.sleep(0.05)
        started = time.perf_counter()
        await ads.close()
        results = await asyncio.gather(*in_flight, return_exceptions=True)
        closing = time.perf_counter() - started
    finally:
        server.call(server.server.end_stall)

    assert closing < 1.0
    assert all(isinstance(r, AdsConnectionError) for r in results)
    assert {r.code for r in results if isinstance(r, AdsError)} == {
        AdsReturnCode.CLIENT_PORT_NOT_OPEN
    }


async def test_the_next_request_reconnects_after_the_connection_dropped(
    client: AdsClient, server: ServerThread
) -> None:
    assert (await client.read_state()).ads_state is AdsState.RUN
    server.call(server.server.drop_connections)
    await asyncio.sleep(0.05)

    assert (await client.read_state()).ads_state is AdsState.RUN
    assert client.connection.stats.losses == 1
    assert client.connection.stats.connects == 2


async def test_discover_net_id_over_udp(server: ServerThread) -> None:
    assert await discover_net_id("127.0.0.1", port=server.udp.port) == NET_ID


async def test_route_password_from_env_reaches_the_target_and_no_log(
    server: ServerThread,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
    capfd: pytest.CaptureFixture[str],
) -> None:
    caplog.set_level(logging.DEBUG)
    monkeypatch.setenv("FASTCS_ETHERCAT_TEST_ROUTE_PASSWORD", ROUTE_PASSWORD)
    route = RouteConfig(password_env="FASTCS_ETHERCAT_TEST_ROUTE_PASSWORD")

    await add_route(
        "127.0.0.1",
        port=server.udp.port,
        local_net_id="192.0.2.99.1.1",
        host_address="127.0.0.1",
        user=route.user,
        password=route.password(),
        route_name="fastcs-ethercat-test",
    )
    with pytest.raises(AdsRouteError) as refused:
        await add_route(
            "127.0.0.1",
            port=server.udp.port,
            local_net_id="192.0.2.99.1.1",
            host_address="127.0.0.1",
            user=route.user,
            password=SecretStr("wrong-" + ROUTE_PASSWORD),
        )

    added = server.call(lambda: list(server.udp.routes))
    assert [(r.name, str(r.netid), r.host, r.user) for r in added] == [
        ("fastcs-ethercat-test", "192.0.2.99.1.1", "127.0.0.1", ROUTE_USER)
    ]
    output = capfd.readouterr()
    for text in (caplog.text, output.out, output.err, str(refused.value), repr(route)):
        assert ROUTE_PASSWORD not in text


async def test_a_sample_in_the_same_write_as_its_handle_is_not_lost() -> None:
    """The cause of the old race: the first sample may follow the answer to
    AddDeviceNotification at once, in the same TCP segment; the handle is
    registered the moment that answer is read, so the sample finds it."""
    handle = 0x4242

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        reassembler = FrameReassembler()
        while data := await reader.read(4096):
            for request in reassembler.feed(data):
                answer = request.response(
                    AddDeviceNotificationResponse(0, handle).encode()
                )
                sample = AmsPacket(
                    target=request.source,
                    source=request.target,
                    command=AmsCommand.DEVICE_NOTIFICATION,
                    payload=DeviceNotification(
                        (NotificationStamp(1, (NotificationSample(handle, b"\x07"),)),)
                    ).encode(),
                )
                writer.write(encode_packet(answer) + encode_packet(sample))

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    received: list[Notification] = []
    try:
        async with AdsClient("127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=port) as ads:
            added = await ads.add_notification(INPUTS, 0, 1, received.append)
    finally:
        server.close()

    assert added.notification == handle
    assert [(n.handle, n.data) for n in received] == [(handle, b"\x07")]
