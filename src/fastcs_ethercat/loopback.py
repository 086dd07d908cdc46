"""The EPICS environment that keeps CA and PVA on loopback, for everything
this project starts itself: the demo, the benchmarks, the tests."""

from __future__ import annotations

from typing import Final

LOOPBACK: Final = "127.0.0.1"
"""The only address a server this project starts binds, and the only one
its clients send to."""

EPICS_LOOPBACK_ENV: Final = {
    "EPICS_CA_AUTO_ADDR_LIST": "NO",
    "EPICS_CA_ADDR_LIST": LOOPBACK,
    "EPICS_CAS_INTF_ADDR_LIST": LOOPBACK,
    "EPICS_CAS_AUTO_BEACON_ADDR_LIST": "NO",
    "EPICS_CAS_BEACON_ADDR_LIST": LOOPBACK,
    "EPICS_PVA_AUTO_ADDR_LIST": "NO",
    "EPICS_PVA_ADDR_LIST": LOOPBACK,
    "EPICS_PVAS_INTF_ADDR_LIST": LOOPBACK,
    "EPICS_PVAS_AUTO_BEACON_ADDR_LIST": "NO",
    "EPICS_PVAS_BEACON_ADDR_LIST": LOOPBACK,
}
"""No search, beacon or server interface beyond 127.0.0.1."""
