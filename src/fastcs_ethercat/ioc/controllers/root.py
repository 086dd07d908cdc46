"""The root controller: connection state, PLC and device info, statistics.

Statistics come from the pollers through a `StatsSource` the app supplies,
read once a second; nothing here raises out of its scan.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from fastcs.attributes import AttrR
from fastcs.controllers import Controller
from fastcs.datatypes import Bool, Int, String
from fastcs.methods import scan

from fastcs_ethercat.ioc.controllers.post import post
from fastcs_ethercat.ioc.datatypes import ExactFloat
from fastcs_ethercat.ioc.plan import SystemPlan

STATS_PERIOD_S: Final = 1.0
ROOT_LEAVES: Final = (
    "Connected",
    "Target",
    "NetId",
    "DeviceName",
    "DeviceVersion",
    "SymbolVersion",
    "Masters",
    "Terminals",
    "PvCount",
    "Unserved",
    "PollCycleTime",
    "PollRate",
    "AdsRequestRate",
    "PollErrors",
    "LastError",
    "ConnectionState",
    "Reconnects",
    "LastRecovery",
    "ChainChanges",
    "InvalidPvs",
)


@dataclass(frozen=True)
class PollStats:
    """What the pollers report, summed over all masters."""

    connected: bool = False
    cycle_time_ms: float = 0.0
    """Duration of the last poll cycle (slowest master)."""
    poll_rate_hz: float = 0.0
    requests_per_second: float = 0.0
    errors: int = 0
    last_error: str = ""
    state: str = "CONNECTED"
    """The supervisor's view: CONNECTED, DISCONNECTED, STOPPED, RESYNCING."""
    reconnects: int = 0
    last_recovery_s: float = 0.0
    chain_changes: str = ""
    invalid: int = 0
    """Attributes in INVALID alarm now."""
    symbol_version: int = -1
    """The symbol version served now (-1: unknown)."""


StatsSource = Callable[[], PollStats]


class RootController(Controller):
    """`<prefix>`: the target and how the IOC is doing."""

    def __init__(
        self,
        prefix: str,
        plan: SystemPlan,
        target: str,
        leaves: Mapping[str, str] | None = None,
        stats: StatsSource | None = None,
    ) -> None:
        super().__init__(description=f"EtherCAT on {plan.device_name or target}")
        self.set_path([prefix])
        self.plan = plan
        self.target = target
        self.stats = stats
        self.pv_count = 0
        self.unserved = 0
        names = {leaf: leaf for leaf in ROOT_LEAVES} | dict(leaves or {})
        terminals = sum(len(master.terminals) for master in plan.masters)
        self.attrs: dict[str, AttrR[Any, Any]] = {
            "Connected": AttrR(Bool(), description="Polling the target"),
            "Target": _fixed(String(), target, "ADS host[:port]"),
            "NetId": _fixed(String(), plan.net_id, "AMS NetId of the target"),
            "DeviceName": _fixed(String(), plan.device_name, "TwinCAT device name"),
            "DeviceVersion": _fixed(String(), plan.device_version, "TwinCAT version"),
            "SymbolVersion": _fixed(Int(), plan.symbol_version, "Symbol table version"),
            "Masters": _fixed(Int(), len(plan.masters), "EtherCAT masters served"),
            "Terminals": _fixed(Int(), terminals, "Terminals served"),
            "PvCount": AttrR(Int(), description="PVs served (CA names)"),
            "Unserved": AttrR(Int(), description="Points with no PV (see log)"),
            "PollCycleTime": AttrR(
                ExactFloat(units="ms", prec=2), description="Last poll cycle"
            ),
            "PollRate": AttrR(
                ExactFloat(units="Hz", prec=1), description="Poll cycles per second"
            ),
            "AdsRequestRate": AttrR(
                ExactFloat(units="1/s", prec=1), description="ADS requests per second"
            ),
            "PollErrors": AttrR(Int(), description="Failed poll reads"),
            "LastError": AttrR(String(), description="Last ADS error"),
            "ConnectionState": AttrR(String(), description="Link to the target"),
            "Reconnects": AttrR(Int(), description="Reconnects and resyncs"),
            "LastRecovery": AttrR(
                ExactFloat(units="s", prec=2), description="Last outage, loss to poll"
            ),
            "ChainChanges": AttrR(String(), description="Chain change at reconnect"),
            "InvalidPvs": AttrR(Int(), description="Attributes in INVALID alarm"),
        }
        for leaf, attr in self.attrs.items():
            self.add_attribute(names[leaf], attr)

    @scan(STATS_PERIOD_S)
    async def read_stats(self) -> None:
        """Copy the pollers' statistics; never raises."""
        if self.stats is None:
            return
        try:
            stats = self.stats()
            a = self.attrs
            await post(a["PvCount"], self.pv_count)
            await post(a["Unserved"], self.unserved)
            await post(a["Connected"], stats.connected)
            await post(a["PollCycleTime"], stats.cycle_time_ms)
            await post(a["PollRate"], stats.poll_rate_hz)
            await post(a["AdsRequestRate"], stats.requests_per_second)
            await post(a["PollErrors"], min(stats.errors, 2**31 - 1))
            await post(a["LastError"], stats.last_error[:200])
            await post(a["ConnectionState"], stats.state)
            await post(a["Reconnects"], min(stats.reconnects, 2**31 - 1))
            await post(a["LastRecovery"], stats.last_recovery_s)
            await post(a["ChainChanges"], stats.chain_changes[:200])
            await post(a["InvalidPvs"], min(stats.invalid, 2**31 - 1))
            if stats.symbol_version >= 0:
                await post(a["SymbolVersion"], stats.symbol_version)
        except Exception:  # a scan must never raise
            pass

    async def show_link(self, state: str, error: str) -> None:
        """Publish a change of the link at once, not at the next scan."""
        try:
            a = self.attrs
            await post(a["Connected"], state == "CONNECTED")
            await post(a["ConnectionState"], state)
            if error:
                await post(a["LastError"], error[:200])
        except Exception:  # never stop the caller (the supervisor)
            pass


def _fixed(datatype: Any, value: Any, text: str) -> AttrR[Any, Any]:
    """An attribute whose value is known before serving and never changes."""
    return AttrR(datatype, initial_value=datatype.validate(value), description=text)
