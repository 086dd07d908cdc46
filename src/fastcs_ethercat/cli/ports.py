"""EPICS server ports for the demo on a host that may already run an IOC.

Two CA servers on one host can share UDP 5064 but not TCP 5064: the second
one takes a random TCP port and then answers searches only some of the
time. The demo therefore checks the default ports first and, when another
server holds them, serves on free ports of its own and says so.
"""

from __future__ import annotations

import socket
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from fastcs_ethercat.loopback import LOOPBACK
from fastcs_ethercat.process import free_port

CA_SERVER_PORT: Final = 5064
PVA_SERVER_PORT: Final = 5075
PVA_BROADCAST_PORT: Final = 5076


@dataclass(frozen=True)
class DemoPorts:
    """The ports the demo serves on, and whether the defaults were busy."""

    ca: int
    pva: int
    pva_broadcast: int
    moved: bool

    def env(self) -> dict[str, str]:
        """The EPICS variables that put servers and clients on these ports."""
        return {
            "EPICS_CA_SERVER_PORT": str(self.ca),
            "EPICS_PVA_SERVER_PORT": str(self.pva),
            "EPICS_PVA_BROADCAST_PORT": str(self.pva_broadcast),
        }


def demo_ports(environ: Mapping[str, str]) -> DemoPorts:
    """The ports `environ` asks for; else the defaults if free; else free ones."""
    asked = [environ.get(name) for name in DemoPorts(0, 0, 0, False).env()]
    if all(value and value.isdecimal() for value in asked):
        ca, pva, broadcast = (int(value or 0) for value in asked)
        return DemoPorts(ca, pva, broadcast, moved=False)
    if _tcp_free(CA_SERVER_PORT) and _tcp_free(PVA_SERVER_PORT):
        return DemoPorts(CA_SERVER_PORT, PVA_SERVER_PORT, PVA_BROADCAST_PORT, False)
    return DemoPorts(
        ca=free_port(tcp=True, udp=True),
        pva=free_port(tcp=True, udp=False),
        pva_broadcast=free_port(tcp=False, udp=True),
        moved=True,
    )


def _tcp_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((LOOPBACK, port))
        except OSError:
            return False
    return True
