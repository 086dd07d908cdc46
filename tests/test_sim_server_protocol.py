"""The AMS/TCP server byte for byte: framing, routing, errors, many clients."""

from __future__ import annotations

import asyncio
import struct
from collections.abc import AsyncIterator

import pytest

from fastcs_ethercat.ads.commands import (
    ReadDeviceInfoResponse,
    ReadRequest,
    ReadResponse,
    ReadStateResponse,
    WriteRequest,
    WriteResponse,
)
from fastcs_ethercat.ads.constants import (
    RESPONSE_FLAGS,
    AdsReturnCode,
    AdsState,
    AmsCommand,
    IndexGroup,
    StateFlag,
)
from fastcs_ethercat.ads.frames import AmsPacket, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.sim.runner import Simulator, SimulatorConfig
from fastcs_ethercat.sim.server import AmsConnection, AmsServer
from tests.sim_support import (
    CLIENT,
    DEVICE_PORT,
    IO_SERVER_PORT,
    RawClient,
    StandInTarget,
    request,
)

TARGET = StandInTarget().system_net_id
IO_SERVER = AmsAddress(TARGET, IO_SERVER_PORT)
DEVICE = AmsAddress(TARGET, DEVICE_PORT)
READ_INPUTS = ReadRequest(IndexGroup.IO_IMAGE_RW_INPUT_BYTES, 0, 4).encode()


@pytest.fixture
def target() -> StandInTarget:
    return StandInTarget()


@pytest.fixture
async def simulator(target: StandInTarget) -> AsyncIterator[Simulator]:
    simulator = Simulator(target, SimulatorConfig(port=0, udp_port=None))
    await simulator.start()
    yield simulator
    await simulator.stop()


@pytest.fixture
async def client(simulator: Simulator) -> AsyncIterator[RawClient]:
    client = await RawClient.connect(simulator.server.port)
    yield client
    await client.close()


async def test_read_state_response_swaps_addresses_and_keeps_invoke_id(
    client: RawClient,
) -> None:
    sent = request(IO_SERVER, AmsCommand.READ_STATE, invoke_id=0xCAFE)
    answer = await client.call(sent)
    assert answer.target == CLIENT
    assert answer.source == IO_SERVER
    assert answer.command == AmsCommand.READ_STATE
    assert answer.state_flags == RESPONSE_FLAGS
    assert answer.invoke_id == 0xCAFE
    assert answer.error_code == 0
    assert ReadStateResponse.decode(answer.payload) == ReadStateResponse(
        ads_state=AdsState.RUN
    )


async def test_device_info_read_and_write_round_trip(
    client: RawClient, target: StandInTarget
) -> None:
    info = await client.call(request(IO_SERVER, AmsCommand.READ_DEVICE_INFO))
    assert ReadDeviceInfoResponse.decode(info.payload).name == "I/O Server"
    write = WriteRequest(IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES, 8, b"\x01\x02")
    written = await client.call(request(DEVICE, AmsCommand.WRITE, write.encode()))
    assert WriteResponse.decode(written.payload).result == 0
    assert target.outputs[8:10] == b"\x01\x02"


async def test_request_split_into_single_bytes_is_reassembled(
    client: RawClient,
) -> None:
    frame = encode_packet(request(DEVICE, AmsCommand.READ, READ_INPUTS, invoke_id=7))
    for byte in frame:
        await client.send(bytes([byte]))
    answer = await client.receive()
    assert answer.invoke_id == 7
    assert ReadResponse.decode(answer.payload).result == 0


async def test_coalesced_requests_are_all_answered_in_order(client: RawClient) -> None:
    frames = b"".join(
        encode_packet(request(DEVICE, AmsCommand.READ, READ_INPUTS, invoke_id=i))
        for i in range(1, 101)
    )
    await client.send(frames)
    answers = [await client.receive() for _ in range(100)]
    assert [a.invoke_id for a in answers] == list(range(1, 101))


async def test_coalesced_answers_leave_in_one_write(target: StandInTarget) -> None:
    server = AmsServer(target)
    connection = AmsConnection(server)
    writes: list[bytes] = []

    class RecordingTransport(asyncio.Transport):
        def write(self, data: bytes | bytearray | memoryview) -> None:
            writes.append(bytes(data))

        def get_extra_info(self, name: str, default: object = None) -> object:
            return ("127.0.0.1", 1) if name == "peername" else default

        def get_write_buffer_size(self) -> int:
            return 0

        def is_closing(self) -> bool:
            return False

    connection.connection_made(RecordingTransport())
    frames = b"".join(
        encode_packet(request(DEVICE, AmsCommand.READ_STATE, invoke_id=i))
        for i in range(10)
    )
    connection.data_received(frames)
    assert len(writes) == 1
    assert writes[0].count(struct.pack("<HH", AmsCommand.READ_STATE, 5)) == 10


async def test_unknown_net_id_gets_ams_error_target_machine_not_found(
    client: RawClient,
) -> None:
    stranger = AmsAddress(AmsNetId.parse("1.2.3.4.5.6"), IO_SERVER_PORT)
    answer = await client.call(request(stranger, AmsCommand.READ_STATE))
    assert answer.error_code == AdsReturnCode.TARGET_MACHINE_NOT_FOUND
    assert answer.source == stranger
    assert answer.payload == b""


async def test_device_net_id_is_served(
    client: RawClient, target: StandInTarget
) -> None:
    device = AmsAddress(target.device_net_id, IO_SERVER_PORT)
    answer = await client.call(request(device, AmsCommand.READ_STATE))
    assert answer.error_code == 0
    assert answer.source == device


async def test_unknown_command_gets_an_ams_error_and_the_connection_lives(
    client: RawClient,
) -> None:
    answer = await client.call(request(IO_SERVER, 0x55, b"\x00" * 8, invoke_id=3))
    assert answer.invoke_id == 3
    assert answer.error_code == AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
    again = await client.call(request(IO_SERVER, AmsCommand.READ_STATE))
    assert again.error_code == 0


async def test_payload_of_wrong_length_gets_invalid_size(client: RawClient) -> None:
    answer = await client.call(request(DEVICE, AmsCommand.READ, b"\x20\xf0\x00"))
    assert answer.error_code == 0
    assert ReadResponse.decode(answer.payload) == ReadResponse(
        result=AdsReturnCode.DEVICE_INVALID_SIZE
    )


async def test_responses_and_notifications_from_clients_are_not_answered(
    client: RawClient,
) -> None:
    stray = AmsPacket(
        target=IO_SERVER,
        source=CLIENT,
        command=AmsCommand.READ_STATE,
        state_flags=RESPONSE_FLAGS,
        payload=b"\x00" * 8,
    )
    notification = request(DEVICE, AmsCommand.DEVICE_NOTIFICATION, b"\x00" * 8)
    await client.send(encode_packet(stray) + encode_packet(notification))
    answer = await client.call(request(IO_SERVER, AmsCommand.READ_STATE, invoke_id=9))
    assert answer.invoke_id == 9


async def test_unknown_port_answers_target_port_not_found(client: RawClient) -> None:
    answer = await client.call(request(AmsAddress(TARGET, 851), AmsCommand.READ_STATE))
    assert answer.error_code == AdsReturnCode.TARGET_PORT_NOT_FOUND


async def test_target_exception_becomes_device_error(
    client: RawClient, target: StandInTarget
) -> None:
    target.fail_with = RuntimeError("model bug")
    answer = await client.call(request(DEVICE, AmsCommand.READ, READ_INPUTS))
    assert ReadResponse.decode(answer.payload).result == AdsReturnCode.DEVICE_ERROR
    target.fail_with = None
    answer = await client.call(request(DEVICE, AmsCommand.READ, READ_INPUTS))
    assert ReadResponse.decode(answer.payload).result == 0


@pytest.mark.parametrize(
    "garbage",
    [
        pytest.param(b"\x01\x00" + struct.pack("<I", 32) + bytes(32), id="reserved"),
        pytest.param(b"\x00\x00" + struct.pack("<I", 5) + bytes(5), id="too-short"),
        pytest.param(b"\x00\x00" + struct.pack("<I", 0xFFFF_FFF0), id="oversized"),
        pytest.param(
            b"\x00\x00" + struct.pack("<I", 40) + bytes(32) + bytes(8), id="bad-length"
        ),
    ],
)
async def test_broken_framing_closes_only_that_connection(
    simulator: Simulator, client: RawClient, garbage: bytes
) -> None:
    bystander = await RawClient.connect(simulator.server.port)
    await client.send(garbage)
    assert await client.closed_by_server()
    answer = await bystander.call(request(IO_SERVER, AmsCommand.READ_STATE))
    assert answer.error_code == 0
    fresh = await RawClient.connect(simulator.server.port)
    assert (await fresh.call(request(IO_SERVER, AmsCommand.READ_STATE))).error_code == 0
    await fresh.close()
    await bystander.close()
    assert simulator.server.counters.bad_frames == 1


async def test_concurrent_clients_get_only_their_own_answers(
    simulator: Simulator,
) -> None:
    clients = [await RawClient.connect(simulator.server.port) for _ in range(8)]

    async def run(index: int, client: RawClient) -> list[tuple[int, AmsAddress]]:
        source = AmsAddress(AmsNetId((10, 0, 0, index, 1, 1)), 30_000 + index)
        frames = b"".join(
            encode_packet(
                request(
                    IO_SERVER,
                    AmsCommand.READ_STATE,
                    invoke_id=index * 1000 + i,
                    source=source,
                )
            )
            for i in range(50)
        )
        await client.send(frames)
        answers = [await client.receive() for _ in range(50)]
        return [(a.invoke_id, a.target) for a in answers]

    results = await asyncio.gather(*(run(i, c) for i, c in enumerate(clients)))
    for index, answers in enumerate(results):
        source = AmsAddress(AmsNetId((10, 0, 0, index, 1, 1)), 30_000 + index)
        assert answers == [(index * 1000 + i, source) for i in range(50)]
    for client in clients:
        await client.close()


async def test_counters_count_commands_and_index_groups(
    simulator: Simulator, client: RawClient
) -> None:
    await client.call(request(IO_SERVER, AmsCommand.READ_STATE))
    for _ in range(3):
        await client.call(request(DEVICE, AmsCommand.READ, READ_INPUTS))
    snapshot = simulator.server.counters.snapshot()
    assert snapshot["total"] == 4
    assert snapshot["commands"] == {"READ": 3, "READ_STATE": 1}
    assert snapshot["index_groups"] == {"0xF020": 3}
    assert snapshot["connections_accepted"] == 1


async def test_response_flag_is_set_on_every_answer(client: RawClient) -> None:
    answer = await client.call(request(DEVICE, AmsCommand.READ, READ_INPUTS))
    assert answer.state_flags & StateFlag.RESPONSE
    assert answer.state_flags & StateFlag.ADS_COMMAND
