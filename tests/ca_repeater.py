"""A loopback-only stand-in for EPICS' caRepeater, run by the test session.

Every CA client (caget, aioca, the IOC's own CA links) checks at start that a
repeater holds EPICS_CA_REPEATER_PORT and, if none does, spawns `caRepeater`
from PATH. A spawned one binds every interface, outlives the test, and keeps
its spawner's stdout open, so `subprocess.run(..., capture_output=True)`
waits for it until its timeout (the 30 s caget hang). The session sets
EPICS_CA_REPEATER_PORT to this socket on 127.0.0.1: clients find the port
taken and spawn nothing. It does the repeater's job too, so clients stay
quiet and see beacons: it confirms registrations and relays every other
datagram (server beacons) to the registered clients.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from typing import Final

HEADER: Final = struct.Struct(">HHHHII")
"""A CA message header: command, payload size, type, count, p1, p2."""
REPEATER_CONFIRM: Final = 17
REPEATER_REGISTER: Final = 24
RSRV_IS_UP: Final = 13
"""A server beacon; p2 is the server's address (0: take the sender's)."""
LOOPBACK: Final = "127.0.0.1"


def _address(host: str) -> int:
    return struct.unpack(">I", socket.inet_aton(host))[0]


class LoopbackRepeater:
    """A CA repeater on a free UDP port of 127.0.0.1, served by a thread."""

    def __init__(self) -> None:
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.bind((LOOPBACK, 0))
        self._socket.settimeout(0.2)
        self.port: int = self._socket.getsockname()[1]
        self.clients: set[tuple[str, int]] = set()
        self._stopping = threading.Event()
        self._thread = threading.Thread(
            target=self._serve, name="ca-repeater", daemon=True
        )

    def start(self) -> LoopbackRepeater:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stopping.set()
        self._thread.join(5)
        self._socket.close()

    def _serve(self) -> None:
        while not self._stopping.is_set():
            try:
                data, sender = self._socket.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            self.handle(data, sender)

    def handle(self, data: bytes, sender: tuple[str, int]) -> None:
        """Confirm a registration (an empty datagram registers old clients);
        relay anything else to every other registered client."""
        command = HEADER.unpack_from(data)[0] if len(data) >= HEADER.size else None
        if command == REPEATER_REGISTER or not data:
            self.clients.add(sender)
            confirm = HEADER.pack(REPEATER_CONFIRM, 0, 0, 0, 0, _address(sender[0]))
            self._send(confirm, sender)
            return
        if command == RSRV_IS_UP and HEADER.unpack_from(data)[5] == 0:
            fields = list(HEADER.unpack_from(data))
            fields[5] = _address(sender[0])
            data = HEADER.pack(*fields) + data[HEADER.size :]
        for client in list(self.clients):
            if client != sender:
                self._send(data, client)

    def _send(self, data: bytes, client: tuple[str, int]) -> None:
        try:
            self._socket.sendto(data, client)
        except OSError:
            with contextlib.suppress(KeyError):
                self.clients.remove(client)
