"""ADS device notifications of one client connection, as TwinCAT pushes them.

A registration samples its value every cycle time (100 ns units, never more
often than the simulator's task cycle); cyclic modes queue every sample,
on-change modes only a value that differs from the last one queued. Queued
samples wait at most their max delay (a max delay ending before the next
tick sends at this one), then every due sample of a connection leaves in one
DeviceNotification frame per (server address, client address) pair, all
frames of a tick in one transport write. Stamps are real FILETIMEs
of the moment the value was sampled.

The first value is sampled on the tick after the registration, never in the
same write as the AddDeviceNotification response: AdsLib registers a handle
only after it has seen the response.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Final

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    DeviceNotification,
    NotificationSample,
    NotificationStamp,
    filetime_from_unix_ns,
)
from fastcs_ethercat.ads.constants import AdsReturnCode, AmsCommand, TransmissionMode
from fastcs_ethercat.ads.frames import AmsPacket, encode_packet
from fastcs_ethercat.ads.netid import AmsAddress

NANOSECONDS_PER_UNIT: Final = 100
"""Cycle time and max delay travel in 100 ns units."""

ON_CHANGE_BY_MODE: Final[Mapping[int, bool]] = {
    TransmissionMode.CLIENT_CYCLE: False,
    TransmissionMode.SERVER_CYCLE: False,
    TransmissionMode.SERVER_CYCLE_2: False,
    TransmissionMode.CLIENT_ON_CHANGE: True,
    TransmissionMode.SERVER_ON_CHANGE: True,
    TransmissionMode.SERVER_ON_CHANGE_2: True,
}
"""The modes served, and whether each sends only a changed value (a cyclic
mode sends every sample); any other mode is refused."""

MAX_NOTIFICATION_SIZE: Final = 0x10000
"""Largest value one notification watches; larger asks answer 0x717."""

MAX_HANDLES_PER_CONNECTION: Final = 10_000
"""More registrations on one connection answer 0x716 (no more handles)."""

ValueReader = Callable[[AmsAddress, int, int, int], tuple[int, bytes]]
"""target.read(address, group, offset, length) -> (result, data)."""


class HandleAllocator:
    """Server-wide notification handles, unique across connections."""

    def __init__(self, first: int = 0) -> None:
        self._counter: Iterator[int] = itertools.count(first)

    def allocate(self) -> int:
        """The next handle in 1..0xFFFFFFFF (0 is never a valid handle)."""
        return next(self._counter) % 0xFFFF_FFFF + 1


@dataclass(slots=True)
class Subscription:
    """One AddDeviceNotification: what to sample, how often, whom to tell."""

    handle: int
    server: AmsAddress
    """The address the client registered with; notifications come from it."""
    client: AmsAddress
    """The client's NetId and port; notifications go to it."""
    request: AddDeviceNotificationRequest
    """What it watches, in which mode, how often and how late at most."""
    on_change: bool
    next_sample_ns: int
    last_data: bytes | None = None

    @property
    def cycle_ns(self) -> int:
        return self.request.cycle_time * NANOSECONDS_PER_UNIT

    @property
    def max_delay_ns(self) -> int:
        return self.request.max_delay * NANOSECONDS_PER_UNIT


@dataclass(slots=True)
class _Batch:
    """Samples queued for one (server, client) pair, oldest deadline first."""

    deadline_ns: int
    stamps: list[NotificationStamp] = field(default_factory=list)


class NotificationRegistry:
    """The notifications one connection registered, sampled on every tick."""

    def __init__(
        self,
        read_value: ValueReader,
        handles: HandleAllocator,
        *,
        max_handles: int = MAX_HANDLES_PER_CONNECTION,
    ) -> None:
        self._read_value = read_value
        self._handles = handles
        self._max_handles = max_handles
        self._subscriptions: dict[int, Subscription] = {}
        self._batches: dict[tuple[AmsAddress, AmsAddress], _Batch] = {}

    def __len__(self) -> int:
        return len(self._subscriptions)

    def handles(self) -> list[int]:
        return list(self._subscriptions)

    def add(
        self,
        packet: AmsPacket,
        request: AddDeviceNotificationRequest,
        now_ns: int,
    ) -> tuple[int, int]:
        """Register; return (result, handle). The value must be readable now."""
        on_change = ON_CHANGE_BY_MODE.get(request.transmission_mode)
        if on_change is None:
            return AdsReturnCode.DEVICE_TRANSMISSION_MODE_NOT_SUPPORTED, 0
        if not 0 < request.length <= MAX_NOTIFICATION_SIZE:
            return AdsReturnCode.DEVICE_INVALID_WATCH_SIZE, 0
        if len(self._subscriptions) >= self._max_handles:
            return AdsReturnCode.DEVICE_NO_MORE_HANDLES, 0
        result, value = self._read(packet.target, request)
        if result != AdsReturnCode.NO_ERROR:
            return result, 0
        if len(value) < request.length:
            # Longer than what it watches (a symbol by handle): refused, not
            # accepted to stay silent. TwinCAT's code for it is unconfirmed.
            return AdsReturnCode.DEVICE_INVALID_SIZE, 0
        handle = self._handles.allocate()
        self._subscriptions[handle] = Subscription(
            handle, packet.target, packet.source, request, on_change, now_ns + 1
        )
        return AdsReturnCode.NO_ERROR, handle

    def _read(
        self, server: AmsAddress, watched: AddDeviceNotificationRequest
    ) -> tuple[int, bytes]:
        """(result, value) of what a registration watches, read now."""
        return self._read_value(
            server, watched.index_group, watched.index_offset, watched.length
        )

    def delete(self, packet: AmsPacket, handle: int) -> int:
        """Unregister a handle this connection owns at the address asked."""
        subscription = self._subscriptions.get(handle)
        if subscription is None or subscription.server != packet.target:
            return AdsReturnCode.DEVICE_NOTIFY_HANDLE_INVALID
        del self._subscriptions[handle]
        return AdsReturnCode.NO_ERROR

    def clear(self) -> None:
        self._subscriptions.clear()
        self._batches.clear()

    def tick(
        self,
        now_ns: int,
        wall_ns: int,
        *,
        send: bool = True,
        next_tick_ns: int | None = None,
    ) -> tuple[list[bytes], int]:
        """Sample what is due; return (the frames due now, samples in them).

        Due are the samples whose max delay ends by now, and, given the time
        of the next tick, those whose max delay ends before it: held until
        then they would leave late (Beckhoff: sent "at the latest when this
        time has elapsed"), so a max delay below one task cycle sends at the
        tick that sampled. With `send` false (a stalled server) values are
        still sampled but nothing is handed out; queued samples then leave on
        a later tick.
        """
        if self._subscriptions:
            self._sample(now_ns, filetime_from_unix_ns(wall_ns))
        if not send or not self._batches:
            return [], 0
        due = now_ns if next_tick_ns is None else max(now_ns, next_tick_ns - 1)
        return self._flush(due)

    def _sample(self, now_ns: int, filetime: int) -> None:
        stamps: dict[tuple[AmsAddress, AmsAddress], list[NotificationSample]] = {}
        for sub in self._subscriptions.values():
            if now_ns < sub.next_sample_ns:
                continue
            following = sub.next_sample_ns + sub.cycle_ns
            sub.next_sample_ns = (
                following if following > now_ns else now_ns + sub.cycle_ns
            )
            result, data = self._read(sub.server, sub.request)
            if result != AdsReturnCode.NO_ERROR:
                continue
            if sub.on_change and data == sub.last_data:
                continue
            sub.last_data = data
            key = (sub.server, sub.client)
            stamps.setdefault(key, []).append(NotificationSample(sub.handle, data))
            batch = self._batches.get(key)
            deadline = now_ns + sub.max_delay_ns
            if batch is None:
                self._batches[key] = _Batch(deadline)
            elif deadline < batch.deadline_ns:
                batch.deadline_ns = deadline
        for key, samples in stamps.items():
            self._batches[key].stamps.append(
                NotificationStamp(filetime, tuple(samples))
            )

    def _flush(self, now_ns: int) -> tuple[list[bytes], int]:
        frames: list[bytes] = []
        samples = 0
        for key, batch in list(self._batches.items()):
            if batch.deadline_ns > now_ns:
                continue
            del self._batches[key]
            server, client = key
            samples += sum(len(stamp.samples) for stamp in batch.stamps)
            notification = AmsPacket(
                target=client,
                source=server,
                command=AmsCommand.DEVICE_NOTIFICATION,
                payload=DeviceNotification(tuple(batch.stamps)).encode(),
            )
            frames.append(encode_packet(notification))
        return frames, samples
