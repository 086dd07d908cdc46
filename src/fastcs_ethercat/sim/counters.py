"""Counts of what the simulator served, so tests and benchmarks can count round
trips (how many requests per command and per index group) without sniffing.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Final

from fastcs_ethercat.ads.constants import AmsCommand
from fastcs_ethercat.ads.frames import AmsPacket

_GROUP_COMMANDS: Final = frozenset(
    {
        AmsCommand.READ,
        AmsCommand.WRITE,
        AmsCommand.READ_WRITE,
        AmsCommand.ADD_DEVICE_NOTIFICATION,
    }
)
"""Commands whose payload starts with an index group (u32)."""


def command_name(command_id: int) -> str:
    """A readable key for a command id (AmsCommand name, or the number)."""
    try:
        return AmsCommand(command_id).name
    except ValueError:
        return str(command_id)


def request_index_group(packet: AmsPacket) -> int | None:
    """The index group a request addresses, if its command carries one."""
    if packet.command in _GROUP_COMMANDS and len(packet.payload) >= 4:
        return int.from_bytes(packet.payload[:4], "little")
    return None


@dataclass
class RequestCounters:
    """Requests per command and per index group, plus what the server pushed."""

    total: int = 0
    by_command: Counter[int] = field(default_factory=Counter)
    by_group: Counter[int] = field(default_factory=Counter)
    notification_frames: int = 0
    notification_samples: int = 0
    connections_accepted: int = 0
    bad_frames: int = 0

    def count_request(self, packet: AmsPacket) -> None:
        """Count one request as it arrives (before any fault or routing)."""
        self.total += 1
        self.by_command[int(packet.command)] += 1
        group = request_index_group(packet)
        if group is not None:
            self.by_group[group] += 1

    def count_notifications(self, frames: int, samples: int) -> None:
        self.notification_frames += frames
        self.notification_samples += samples

    def reset(self) -> None:
        self.total = 0
        self.by_command.clear()
        self.by_group.clear()
        self.notification_frames = 0
        self.notification_samples = 0
        self.connections_accepted = 0
        self.bad_frames = 0

    def snapshot(self) -> dict[str, Any]:
        """A JSON-ready copy: command names and groups as "0xF080" strings."""
        return {
            "total": self.total,
            "commands": {
                command_name(command): count
                for command, count in sorted(self.by_command.items())
            },
            "index_groups": {
                f"0x{group:X}": count for group, count in sorted(self.by_group.items())
            },
            "notifications": {
                "frames": self.notification_frames,
                "samples": self.notification_samples,
            },
            "connections_accepted": self.connections_accepted,
            "bad_frames": self.bad_frames,
        }
