"""An in-process ADS client for a `SimTarget`: requests are encoded with the
codec into AMS packets and answers decoded the same way, with no socket.

Tests, benchmarks and tools use it to talk to the model exactly as a client
would over TCP, minus the transport.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Final, Protocol

from fastcs_ethercat.ads import commands
from fastcs_ethercat.ads.commands import AdsRequest, AdsResponse
from fastcs_ethercat.ads.constants import (
    REQUEST_FLAGS,
    AmsPort,
)
from fastcs_ethercat.ads.frames import AmsPacket
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId

CLIENT_ADDRESS: Final = AmsAddress(AmsNetId.parse("192.168.0.100.1.1"), 32905)
"""Where the probe's requests come from (any address works)."""


class PacketHandler(Protocol):
    def handle(self, packet: AmsPacket) -> AmsPacket | None: ...


class ProbeError(Exception):
    """An AMS-level error (no response payload), with its code."""

    def __init__(self, code: int) -> None:
        super().__init__(f"AMS error 0x{code:X}")
        self.code = code


@dataclass
class SimProbe:
    """Sends encoded requests to one AMS address of a target."""

    target: PacketHandler
    address: AmsAddress
    source: AmsAddress = CLIENT_ADDRESS
    _invoke: itertools.count[int] = field(default_factory=lambda: itertools.count(1))

    def at(self, port: int, net_id: AmsNetId | None = None) -> SimProbe:
        """A probe for another port (and NetId) of the same target."""
        return SimProbe(
            self.target, AmsAddress(net_id or self.address.netid, port), self.source
        )

    def packet(self, request: AdsRequest) -> AmsPacket:
        return AmsPacket(
            target=self.address,
            source=self.source,
            command=request.command,
            state_flags=REQUEST_FLAGS,
            invoke_id=next(self._invoke),
            payload=request.encode(),
        )

    def exchange(self, request: AdsRequest) -> tuple[AmsPacket, AmsPacket]:
        """The request packet and the target's response packet."""
        sent = self.packet(request)
        answer = self.target.handle(sent)
        if answer is None:
            raise AssertionError(f"no answer to {request!r}")
        return sent, answer

    def request(self, request: AdsRequest) -> AdsResponse:
        _, answer = self.exchange(request)
        if answer.error_code:
            raise ProbeError(answer.error_code)
        return commands.decode_response(int(answer.command), answer.payload)

    # -- the commands -----------------------------------------------------------

    def read(self, group: int, offset: int, length: int) -> commands.ReadResponse:
        answer = self.request(commands.ReadRequest(group, offset, length))
        assert isinstance(answer, commands.ReadResponse)
        return answer

    def write(self, group: int, offset: int, data: bytes) -> commands.WriteResponse:
        answer = self.request(commands.WriteRequest(group, offset, data))
        assert isinstance(answer, commands.WriteResponse)
        return answer

    def read_write(
        self, group: int, offset: int, length: int, data: bytes
    ) -> commands.ReadWriteResponse:
        answer = self.request(commands.ReadWriteRequest(group, offset, length, data))
        assert isinstance(answer, commands.ReadWriteResponse)
        return answer

    def read_state(self) -> commands.ReadStateResponse:
        answer = self.request(commands.ReadStateRequest())
        assert isinstance(answer, commands.ReadStateResponse)
        return answer

    def device_info(self) -> commands.ReadDeviceInfoResponse:
        answer = self.request(commands.ReadDeviceInfoRequest())
        assert isinstance(answer, commands.ReadDeviceInfoResponse)
        return answer

    def write_control(
        self, ads_state: int, device_state: int = 0
    ) -> commands.WriteControlResponse:
        answer = self.request(commands.WriteControlRequest(ads_state, device_state))
        assert isinstance(answer, commands.WriteControlResponse)
        return answer


def device_probe(
    target: PacketHandler, system_net_id: AmsNetId, device: int = 1
) -> SimProbe:
    """A probe on device `device`'s symbol port (27904 + device)."""
    return SimProbe(target, AmsAddress(system_net_id, AmsPort.DEVICE_BASE + device))


__all__ = ["CLIENT_ADDRESS", "ProbeError", "SimProbe", "device_probe"]
