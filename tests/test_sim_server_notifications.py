"""Device notifications: cycle time, on change, max delay, stamps, handles."""

from __future__ import annotations

import asyncio
import struct
import time
from collections.abc import AsyncIterator

import pytest

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    AddDeviceNotificationResponse,
    DeleteDeviceNotificationRequest,
    DeleteDeviceNotificationResponse,
    DeviceNotification,
    ReadWriteResponse,
)
from fastcs_ethercat.ads.constants import (
    AdsReturnCode,
    AmsCommand,
    IndexGroup,
    TransmissionMode,
)
from fastcs_ethercat.ads.frames import AmsPacket
from fastcs_ethercat.ads.netid import AmsAddress
from fastcs_ethercat.ads.sums import (
    SumAddNotificationsRequest,
    SumAddNotificationsResponse,
    SumDeleteNotificationsRequest,
    SumDeleteNotificationsResponse,
)
from fastcs_ethercat.sim.notifications import HandleAllocator, NotificationRegistry
from fastcs_ethercat.sim.runner import Simulator, SimulatorConfig
from tests.ads_codec import decode_packet, filetime_to_unix_ns
from tests.sim_support import CLIENT, DEVICE_PORT, RawClient, StandInTarget, request

MS = 1_000_000
"""Nanoseconds per millisecond."""
UNITS_PER_MS = 10_000
"""Cycle time and max delay units (100 ns) per millisecond."""
INPUTS = IndexGroup.IO_IMAGE_RW_INPUT_BYTES
WALL = 1_700_000_000 * 1_000_000_000


def add_request(
    mode: int = TransmissionMode.SERVER_CYCLE,
    cycle_ms: float = 10,
    max_delay_ms: float = 0,
    offset: int = 0,
    length: int = 2,
) -> AddDeviceNotificationRequest:
    return AddDeviceNotificationRequest(
        INPUTS,
        offset,
        length,
        mode,
        max_delay=round(max_delay_ms * UNITS_PER_MS),
        cycle_time=round(cycle_ms * UNITS_PER_MS),
    )


class Registry:
    """A registry on a stand-in target, driven by a hand-made clock."""

    def __init__(self) -> None:
        self.target = StandInTarget()
        self.device = AmsAddress(self.target.system_net_id, DEVICE_PORT)
        self.registry = NotificationRegistry(self.target.read, HandleAllocator())

    def add(self, add: AddDeviceNotificationRequest, now_ms: float = -1) -> int:
        """Register (by default just before the tick at t = 0)."""
        packet = request(self.device, AmsCommand.ADD_DEVICE_NOTIFICATION)
        result, handle = self.registry.add(packet, add, int(now_ms * MS))
        assert result == AdsReturnCode.NO_ERROR
        return handle

    def tick(self, now_ms: float) -> list[tuple[AmsPacket, DeviceNotification]]:
        frames, _ = self.registry.tick(int(now_ms * MS), WALL + int(now_ms * MS))
        packets = [decode_packet(frame) for frame in frames]
        return [(p, DeviceNotification.decode(p.payload)) for p in packets]

    def set_counter(self, value: int) -> None:
        struct.pack_into("<H", self.target.inputs, 0, value)


@pytest.fixture
def registry() -> Registry:
    return Registry()


def test_cyclic_notification_honours_the_cycle_time(registry: Registry) -> None:
    handle = registry.add(add_request(cycle_ms=30))
    sent_at = [t for t in range(0, 100) if registry.tick(t)]
    assert sent_at == [0, 30, 60, 90]
    registry.set_counter(7)
    ((packet, notification),) = registry.tick(120)
    assert packet.command == AmsCommand.DEVICE_NOTIFICATION
    assert packet.source == registry.device
    assert packet.target == CLIENT
    ((sample,),) = [stamp.samples for stamp in notification.stamps]
    assert sample.handle == handle
    assert sample.data == struct.pack("<H", 7)


def test_on_change_notification_sends_only_changes(registry: Registry) -> None:
    registry.add(add_request(TransmissionMode.SERVER_ON_CHANGE, cycle_ms=1))
    assert len(registry.tick(0)) == 1  # the first value always goes out
    assert registry.tick(5) == []
    registry.set_counter(42)
    ((_, notification),) = registry.tick(6)
    assert notification.stamps[0].samples[0].data == struct.pack("<H", 42)
    assert registry.tick(7) == []


def test_max_delay_batches_samples_into_one_frame_with_several_stamps(
    registry: Registry,
) -> None:
    registry.add(add_request(cycle_ms=10, max_delay_ms=35))
    frames = []
    for t in range(0, 40, 10):
        registry.set_counter(t)
        frames += registry.tick(t)
    assert frames == []  # the first sample may wait until t = 35
    ((_, notification),) = registry.tick(35)
    stamps = notification.stamps
    assert [s.samples[0].data for s in stamps] == [
        struct.pack("<H", t) for t in (0, 10, 20, 30)
    ]
    times = [filetime_to_unix_ns(s.timestamp) - WALL for s in stamps]
    assert times == [0, 10 * MS, 20 * MS, 30 * MS]


@pytest.mark.parametrize("max_delay_ms", [0, 1, 5, 9.9, 10, 15, 35])
def test_no_sample_leaves_later_than_its_max_delay(
    registry: Registry, max_delay_ms: float
) -> None:
    """A task cycle of 10 ms (the tick says when the next one comes): each
    sample leaves at the last tick before its max delay ends, never after
    (Beckhoff: "at the latest when this time has elapsed"); a max delay
    below one cycle sends at the tick that took the sample."""
    registry.add(add_request(cycle_ms=10, max_delay_ms=max_delay_ms))
    late: list[float] = []
    sent = 0
    for t in range(0, 200, 10):
        frames, _ = registry.registry.tick(
            t * MS, WALL + t * MS, next_tick_ns=(t + 10) * MS
        )
        for frame in frames:
            notification = DeviceNotification.decode(decode_packet(frame).payload)
            for stamp in notification.stamps:
                taken = (filetime_to_unix_ns(stamp.timestamp) - WALL) / MS
                sent += 1
                if t - taken > max_delay_ms:
                    late.append(t - taken)
    assert late == []
    assert sent >= 200 // 10 - max_delay_ms // 10 - 1


def test_samples_of_one_tick_share_a_stamp(registry: Registry) -> None:
    first = registry.add(add_request(offset=0))
    second = registry.add(add_request(offset=4, length=4))
    ((_, notification),) = registry.tick(0)
    (stamp,) = notification.stamps
    assert {s.handle for s in stamp.samples} == {first, second}
    assert sorted(len(s.data) for s in stamp.samples) == [2, 4]


def test_client_cycle_and_on_change_modes_are_accepted(registry: Registry) -> None:
    registry.add(add_request(TransmissionMode.CLIENT_CYCLE))
    registry.add(add_request(TransmissionMode.CLIENT_ON_CHANGE))
    assert len(registry.registry) == 2


@pytest.mark.parametrize(
    ("add", "code"),
    [
        (add_request(mode=0), AdsReturnCode.DEVICE_TRANSMISSION_MODE_NOT_SUPPORTED),
        (add_request(mode=99), AdsReturnCode.DEVICE_TRANSMISSION_MODE_NOT_SUPPORTED),
        (add_request(length=0), AdsReturnCode.DEVICE_INVALID_WATCH_SIZE),
        (add_request(length=1 << 20), AdsReturnCode.DEVICE_INVALID_WATCH_SIZE),
        (add_request(offset=4096), AdsReturnCode.DEVICE_INVALID_OFFSET),
    ],
)
def test_bad_registrations_are_refused(
    registry: Registry, add: AddDeviceNotificationRequest, code: int
) -> None:
    packet = request(registry.device, AmsCommand.ADD_DEVICE_NOTIFICATION)
    assert registry.registry.add(packet, add, 0) == (code, 0)


def test_delete_stops_the_notification_and_unknown_handles_fail(
    registry: Registry,
) -> None:
    handle = registry.add(add_request())
    packet = request(registry.device, AmsCommand.DELETE_DEVICE_NOTIFICATION)
    assert registry.registry.delete(packet, handle + 1) == (
        AdsReturnCode.DEVICE_NOTIFY_HANDLE_INVALID
    )
    assert registry.registry.delete(packet, handle) == 0
    assert registry.tick(0) == []


def test_handles_are_unique_across_connections() -> None:
    handles = HandleAllocator()
    target = StandInTarget()
    device = AmsAddress(target.system_net_id, DEVICE_PORT)
    packet = request(device, AmsCommand.ADD_DEVICE_NOTIFICATION)
    registries = [NotificationRegistry(target.read, handles) for _ in range(3)]
    got = [r.add(packet, add_request(), 0)[1] for r in registries for _ in range(5)]
    assert len(set(got)) == 15
    assert 0 not in got


def test_a_stalled_tick_samples_but_sends_later(registry: Registry) -> None:
    registry.add(add_request(cycle_ms=10))
    frames, _ = registry.registry.tick(0, WALL, send=False)
    assert frames == []
    ((_, notification),) = registry.tick(10)
    assert len(notification.stamps) == 2


# -- over TCP -------------------------------------------------------------------


@pytest.fixture
async def simulator() -> AsyncIterator[Simulator]:
    simulator = Simulator(
        StandInTarget(cycle_s=0.002), SimulatorConfig(port=0, udp_port=None)
    )
    await simulator.start()
    yield simulator
    await simulator.stop()


async def test_notifications_over_tcp_with_real_timestamps(
    simulator: Simulator,
) -> None:
    client = await RawClient.connect(simulator.server.port)
    device = AmsAddress(simulator.target.system_net_id, DEVICE_PORT)
    add = add_request(TransmissionMode.SERVER_ON_CHANGE, cycle_ms=5)
    answer = await client.call(
        request(device, AmsCommand.ADD_DEVICE_NOTIFICATION, add.encode())
    )
    added = AddDeviceNotificationResponse.decode(answer.payload)
    assert added.result == 0
    values = []
    before = time.time_ns()
    while len(values) < 5:
        packet = await client.receive()
        assert packet.command == AmsCommand.DEVICE_NOTIFICATION
        assert packet.source == device
        assert packet.target == CLIENT
        for stamp in DeviceNotification.decode(packet.payload).stamps:
            assert before - 1e9 < filetime_to_unix_ns(stamp.timestamp) < time.time_ns()
            for sample in stamp.samples:
                assert sample.handle == added.handle
                values.append(struct.unpack("<H", sample.data)[0])
    assert values == sorted(values)  # the stand-in counts up every tick
    deleted = await client.call(
        request(
            device,
            AmsCommand.DELETE_DEVICE_NOTIFICATION,
            DeleteDeviceNotificationRequest(added.handle).encode(),
            invoke_id=2,
        )
    )
    assert DeleteDeviceNotificationResponse.decode(deleted.payload).result == 0
    assert simulator.server.notification_count == 0
    counters = simulator.server.counters.snapshot()
    assert counters["notifications"]["samples"] >= 5
    assert counters["commands"]["ADD_DEVICE_NOTIFICATION"] == 1
    await client.close()


async def test_notifications_go_away_with_their_connection(
    simulator: Simulator,
) -> None:
    client = await RawClient.connect(simulator.server.port)
    device = AmsAddress(simulator.target.system_net_id, DEVICE_PORT)
    for invoke_id in range(3):
        await client.call(
            request(
                device,
                AmsCommand.ADD_DEVICE_NOTIFICATION,
                add_request().encode(),
                invoke_id=invoke_id,
            )
        )
    assert simulator.server.notification_count == 3
    await client.close()
    for _ in range(100):
        if simulator.server.notification_count == 0:
            break
        await asyncio.sleep(0.01)
    assert simulator.server.notification_count == 0


async def test_malformed_add_request_gets_invalid_size(simulator: Simulator) -> None:
    client = await RawClient.connect(simulator.server.port)
    device = AmsAddress(simulator.target.system_net_id, DEVICE_PORT)
    answer = await client.call(
        request(device, AmsCommand.ADD_DEVICE_NOTIFICATION, b"\x00" * 12)
    )
    assert AddDeviceNotificationResponse.decode(answer.payload).result == (
        AdsReturnCode.DEVICE_INVALID_SIZE
    )
    await client.close()


def test_first_value_waits_for_the_tick_after_the_registration(
    registry: Registry,
) -> None:
    registry.add(add_request(cycle_ms=30), now_ms=0)
    assert registry.tick(0) == []
    assert len(registry.tick(1)) == 1


async def test_sum_add_and_delete_notifications(simulator: Simulator) -> None:
    client = await RawClient.connect(simulator.server.port)
    device = AmsAddress(simulator.target.system_net_id, DEVICE_PORT)
    adds = SumAddNotificationsRequest(
        (add_request(), add_request(offset=4096), add_request(offset=4, length=4))
    )
    answer = await client.call(
        request(device, AmsCommand.READ_WRITE, adds.to_read_write().encode())
    )
    response = ReadWriteResponse.decode(answer.payload)
    assert response.result == 0
    added = SumAddNotificationsResponse.decode(response.data, 3)
    assert added.results == (0, AdsReturnCode.DEVICE_INVALID_OFFSET, 0)
    assert added.handles[1] == 0
    assert simulator.server.notification_count == 2
    deletes = SumDeleteNotificationsRequest((added.handles[0], 12345))
    answer = await client.call(
        request(device, AmsCommand.READ_WRITE, deletes.to_read_write().encode(), 2)
    )
    response = ReadWriteResponse.decode(answer.payload)
    assert SumDeleteNotificationsResponse.decode(response.data, 2).results == (
        0,
        AdsReturnCode.DEVICE_NOTIFY_HANDLE_INVALID,
    )
    assert simulator.server.notification_count == 1
    await client.close()


async def test_add_notification_on_an_unknown_port_is_an_ams_error(
    simulator: Simulator,
) -> None:
    client = await RawClient.connect(simulator.server.port)
    nobody = AmsAddress(simulator.target.system_net_id, 851)
    answer = await client.call(
        request(nobody, AmsCommand.ADD_DEVICE_NOTIFICATION, add_request().encode())
    )
    assert answer.error_code == AdsReturnCode.TARGET_PORT_NOT_FOUND
    assert answer.payload == b""
    await client.close()
