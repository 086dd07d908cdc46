"""Faults switched on at run time: drop, refuse, stall, error and model faults."""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from typing import Any

import pytest

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    AddDeviceNotificationResponse,
    ReadRequest,
    ReadResponse,
    ReadStateResponse,
)
from fastcs_ethercat.ads.constants import (
    AdsState,
    AmsCommand,
    IndexGroup,
    TransmissionMode,
)
from fastcs_ethercat.ads.netid import AmsAddress
from fastcs_ethercat.sim.faults import Fault, FaultError, FaultKind, parse_fault
from fastcs_ethercat.sim.runner import Simulator, SimulatorConfig
from tests.sim_support import (
    DEVICE_PORT,
    IO_SERVER_PORT,
    RawClient,
    StandInTarget,
    request,
)

INPUTS = IndexGroup.IO_IMAGE_RW_INPUT_BYTES
OUTPUTS = IndexGroup.IO_IMAGE_RW_OUTPUT_BYTES


@pytest.fixture
async def simulator() -> AsyncIterator[Simulator]:
    simulator = Simulator(StandInTarget(), SimulatorConfig(port=0, udp_port=None))
    await simulator.start()
    yield simulator
    await simulator.stop()


def device(simulator: Simulator) -> AmsAddress:
    return AmsAddress(simulator.target.system_net_id, DEVICE_PORT)


def io_server(simulator: Simulator) -> AmsAddress:
    return AmsAddress(simulator.target.system_net_id, IO_SERVER_PORT)


async def read_state(simulator: Simulator, client: RawClient) -> ReadStateResponse:
    answer = await client.call(request(io_server(simulator), AmsCommand.READ_STATE))
    return ReadStateResponse.decode(answer.payload)


async def connected_within(port: int, seconds: float) -> RawClient:
    """A client of `port` once the server takes connections again (refused
    ones retried until `seconds` pass)."""
    deadline = time.monotonic() + seconds
    while True:
        try:
            return await RawClient.connect(port)
        except ConnectionRefusedError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.02)


async def test_drop_closes_every_connection_and_new_ones_work(
    simulator: Simulator,
) -> None:
    clients = [await RawClient.connect(simulator.server.port) for _ in range(3)]
    for client in clients:
        await read_state(simulator, client)
    simulator.control.add_fault("drop")
    for client in clients:
        assert await client.closed_by_server()
    fresh = await RawClient.connect(simulator.server.port)
    assert (await read_state(simulator, fresh)).ads_state == AdsState.RUN
    await fresh.close()
    assert simulator.control.faults() == []  # drop is one shot


async def test_refuse_rejects_connects_for_the_given_time(simulator: Simulator) -> None:
    port = simulator.server.port
    open_client = await RawClient.connect(port)
    simulator.control.add_fault("refuse", seconds=0.5)
    started = time.monotonic()
    assert await open_client.closed_by_server()
    with pytest.raises(ConnectionRefusedError):
        await RawClient.connect(port)
    assert simulator.control.faults() == [{"kind": "refuse"}]
    while True:
        try:
            client = await RawClient.connect(port)
            break
        except ConnectionRefusedError:
            assert time.monotonic() - started < 5
            await asyncio.sleep(0.05)
    assert time.monotonic() - started >= 0.45
    assert (await read_state(simulator, client)).ads_state == AdsState.RUN
    await client.close()
    assert simulator.server.port == port


async def test_clearing_faults_ends_a_refusal_early(simulator: Simulator) -> None:
    simulator.control.add_fault("refuse", seconds=60)
    with pytest.raises(ConnectionRefusedError):
        await RawClient.connect(simulator.server.port)
    simulator.control.clear_faults()
    client = await connected_within(simulator.server.port, 1.0)
    await read_state(simulator, client)
    await client.close()


async def test_stall_holds_answers_until_it_ends(simulator: Simulator) -> None:
    client = await RawClient.connect(simulator.server.port)
    simulator.control.add_fault("stall", seconds=0.4)
    started = time.monotonic()
    await client.send(request(io_server(simulator), AmsCommand.READ_STATE, invoke_id=5))
    answer = await client.receive(timeout=5)
    assert time.monotonic() - started >= 0.35
    assert answer.invoke_id == 5
    assert simulator.control.faults() == []
    await client.close()


async def test_stall_without_time_lasts_until_cleared(simulator: Simulator) -> None:
    client = await RawClient.connect(simulator.server.port)
    simulator.control.add_fault("stall")
    await client.send(request(io_server(simulator), AmsCommand.READ_STATE, invoke_id=6))
    with pytest.raises(TimeoutError):
        await client.receive(timeout=0.3)
    assert simulator.control.faults() == [{"kind": "stall"}]
    simulator.control.clear_faults()
    assert (await client.receive()).invoke_id == 6
    await client.close()


async def test_forced_error_answers_its_group_only(simulator: Simulator) -> None:
    client = await RawClient.connect(simulator.server.port)
    simulator.control.add_fault("error", code=0x701, group=INPUTS)

    async def read(group: int) -> int:
        payload = ReadRequest(group, 0, 2).encode()
        answer = await client.call(request(device(simulator), AmsCommand.READ, payload))
        return ReadResponse.decode(answer.payload).result

    async def add_notification(group: int) -> int:
        add = AddDeviceNotificationRequest(
            group, 0, 2, TransmissionMode.SERVER_CYCLE, cycle_time=100_000
        )
        answer = await client.call(
            request(device(simulator), AmsCommand.ADD_DEVICE_NOTIFICATION, add.encode())
        )
        return AddDeviceNotificationResponse.decode(answer.payload).result

    assert await read(INPUTS) == 0x701
    assert await read(OUTPUTS) == 0
    assert await add_notification(INPUTS) == 0x701
    assert await add_notification(OUTPUTS) == 0
    simulator.control.clear_faults()
    assert await read(INPUTS) == 0
    assert await add_notification(INPUTS) == 0
    await client.close()


async def test_model_faults_reach_the_target_and_clear(simulator: Simulator) -> None:
    target = simulator.target
    assert isinstance(target, StandInTarget)
    control = simulator.control
    control.add_fault("slave_state", state="PREOP", address=1002)
    control.add_fault("link_lost", name="Term 3 (EL1014)")
    control.add_fault("online_change", pdo_groups={"Term 2 (EL3104)": "Compact"})
    control.add_fault("stop")
    client = await RawClient.connect(simulator.server.port)
    assert (await read_state(simulator, client)).ads_state == AdsState.STOP
    assert target.calls == [
        ("set_slave_state", (1002, 2, None)),
        ("set_link_lost", ("Term 3 (EL1014)", True, None)),
        ("online_change", ({"Term 2 (EL3104)": "Compact"}, ())),
        ("set_run_state", (False,)),
    ]
    assert [f["kind"] for f in control.faults()] == ["slave_state", "link_lost", "stop"]
    control.clear_faults()
    assert control.faults() == []
    assert target.calls[-1] == ("clear_faults", ())
    assert (await read_state(simulator, client)).ads_state == AdsState.RUN
    await client.close()


@pytest.mark.parametrize(
    ("body", "fault"),
    [
        ({"kind": "drop"}, Fault(FaultKind.DROP)),
        ({"kind": "refuse", "seconds": 2}, Fault(FaultKind.REFUSE, {"seconds": 2.0})),
        ({"kind": "stall"}, Fault(FaultKind.STALL)),
        (
            {"kind": "error", "code": "0x701", "group": 61472},
            Fault(FaultKind.ERROR, {"code": 0x701, "group": 0xF020}),
        ),
        (
            {"kind": "slave_state", "state": "safeop", "device": 1},
            Fault(FaultKind.SLAVE_STATE, {"state": 4, "device": 1}),
        ),
        (
            {"kind": "link_lost", "lost": False, "address": 1001},
            Fault(FaultKind.LINK_LOST, {"lost": False, "address": 1001}),
        ),
    ],
)
def test_fault_requests_are_parsed(body: dict[str, Any], fault: Fault) -> None:
    assert parse_fault(body) == fault


@pytest.mark.parametrize(
    "body",
    [
        [],
        {},
        {"kind": "melt"},
        {"kind": "refuse"},
        {"kind": "refuse", "seconds": -1},
        {"kind": "refuse", "seconds": float("inf")},
        {"kind": "refuse", "seconds": "soon"},
        {"kind": "stall", "seconds": True},
        {"kind": "error"},
        {"kind": "error", "code": 0},
        {"kind": "error", "code": "x"},
        {"kind": "slave_state"},
        {"kind": "slave_state", "state": "NAPPING"},
        {"kind": "slave_state", "state": 5},
        {"kind": "link_lost", "lost": "yes"},
        {"kind": "link_lost", "address": 1001, "name": "Term 1 (EK1100)"},
        {"kind": "link_lost", "name": 7},
        {"kind": "online_change", "pdo_groups": ["Compact"]},
        {"kind": "drop", "extra": 1},
    ],
)
def test_bad_fault_requests_are_rejected(body: Any) -> None:
    with pytest.raises(FaultError):
        parse_fault(body)
