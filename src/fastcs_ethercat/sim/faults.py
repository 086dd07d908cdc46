"""Fault requests: what a test may ask the simulator to break, and checks of
their parameters, shared by the HTTP control API and the Python API.

Transport faults (drop, refuse, stall, error) are carried out by the server;
model faults (slave state, link lost, online change, stop, no sum commands)
by the target.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Final


class FaultKind(StrEnum):
    DROP = "drop"
    """Close every open client connection now (one shot)."""
    REFUSE = "refuse"
    """Stop listening for `seconds` (connects are refused); drops open ones."""
    STALL = "stall"
    """Hold every response (and notification) for `seconds`, or until cleared."""
    ERROR = "error"
    """Answer requests with ADS error `code` (only for index `group` if given).
    With `symbols` (TwinCAT names) only reads touching those symbols fail, per
    item inside a sum read, as TwinCAT reports per-item errors in 0xF080."""
    SLAVE_STATE = "slave_state"
    """Put one slave (`address` or `name`; default all) into an EtherCAT state
    (INIT, PREOP, BOOT, SAFEOP, OP)."""
    LINK_LOST = "link_lost"
    """Lose (`lost`: true, default) or restore the link of one slave (or all)."""
    ONLINE_CHANGE = "online_change"
    """Activate a new configuration (optionally other `pdo_groups`, and without
    the slaves named in `removed`): the symbol version changes, old handles
    become invalid."""
    STOP = "stop"
    """Put the runtime into STOP (ReadState answers 6)."""
    NO_SUM_COMMANDS = "no_sum_commands"
    """Play a target without sum commands: 0xF080, 0xF081 and 0xF082 answered
    0x701 (service not supported) on every port, as older TwinCAT 2, pcdshub's
    ads-async, fastcs-catio's simulator and pyads' test server do; single
    requests are served as ever."""


class FaultError(ValueError):
    """A fault request with a bad kind or bad parameters (HTTP 400)."""


SLAVE_STATES: Final = {"INIT": 1, "PREOP": 2, "BOOT": 3, "SAFEOP": 4, "OP": 8}
"""EtherCAT AL states by name (facts file, section 6)."""


@dataclass(frozen=True)
class Fault:
    """One validated fault request."""

    kind: FaultKind
    params: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind.value, **self.params}


def _number(value: Any, name: str, *, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FaultError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value) or (positive and value <= 0):
        raise FaultError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _integer(value: Any, name: str, low: int, high: int) -> int:
    """An int in [low, high]; also accepts strings like "0xF021" or "1794"."""
    if isinstance(value, str):
        try:
            value = int(value, 0)
        except ValueError:
            raise FaultError(f"{name} must be an integer, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, int):
        raise FaultError(f"{name} must be an integer, got {value!r}")
    if not low <= value <= high:
        raise FaultError(f"{name} must be in {low}..{high}, got {value}")
    return value


def _slave_state(value: Any) -> int:
    if isinstance(value, str) and value.upper() in SLAVE_STATES:
        return SLAVE_STATES[value.upper()]
    state = _integer(value, "state", 0, 0xFF)
    if state & 0x0F not in SLAVE_STATES.values():
        raise FaultError(f"state must be one of {sorted(SLAVE_STATES)}, got {value!r}")
    return state


def _optional_slave(body: Mapping[str, Any]) -> dict[str, Any]:
    """The optional slave selector (EtherCAT address or TwinCAT name; none
    means every slave) and device id."""
    params: dict[str, Any] = {}
    if body.get("address") is not None and body.get("name") is not None:
        raise FaultError("give a slave's address or its name, not both")
    if body.get("address") is not None:
        params["address"] = _integer(body["address"], "address", 0, 0xFFFF)
    if body.get("name") is not None:
        if not isinstance(body["name"], str) or not body["name"]:
            raise FaultError(
                f"name must be a slave's TwinCAT name, got {body['name']!r}"
            )
        params["name"] = body["name"]
    if body.get("device") is not None:
        params["device"] = _integer(body["device"], "device", 1, 0xFFFF)
    return params


def _pdo_groups(value: Any) -> dict[str, str]:
    if not isinstance(value, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in value.items()
    ):
        raise FaultError(
            'pdo_groups maps slave names to PDO groups, e.g. {"Term 2 (EL3104)": '
            '"Compact"}'
        )
    return dict(value)


def _slave_names(value: Any) -> list[str]:
    """A non-empty list of slaves' TwinCAT names."""
    if (
        not isinstance(value, list | tuple)
        or not value
        or not all(isinstance(name, str) and name for name in value)
    ):
        raise FaultError('removed is a list of slave names, e.g. ["Term 7 (EL2024)"]')
    return list(dict.fromkeys(value))


def _symbols(value: Any) -> list[str]:
    """A non-empty list of TwinCAT symbol names (one name alone is accepted)."""
    names = [value] if isinstance(value, str) else value
    if (
        not isinstance(names, list | tuple)
        or not names
        or not all(isinstance(name, str) and name for name in names)
    ):
        raise FaultError(
            'symbols is a list of TwinCAT symbol names, e.g. ["Term 5 (EL3104).'
            'AI Compact Channel 1"]'
        )
    return list(dict.fromkeys(names))


def _check_known(body: Mapping[str, Any], allowed: set[str]) -> None:
    unknown = set(body) - allowed - {"kind"}
    if unknown:
        raise FaultError(f"unknown parameters {sorted(unknown)}")


def parse_fault(body: Any) -> Fault:
    """Validate a fault request such as {"kind": "refuse", "seconds": 2}."""
    if not isinstance(body, Mapping):
        raise FaultError('a fault is a JSON object like {"kind": "drop"}')
    try:
        kind = FaultKind(body.get("kind"))
    except ValueError:
        kinds = ", ".join(k.value for k in FaultKind)
        raise FaultError(
            f"kind must be one of {kinds}, got {body.get('kind')!r}"
        ) from None
    params: dict[str, Any] = {}
    match kind:
        case FaultKind.DROP | FaultKind.STOP | FaultKind.NO_SUM_COMMANDS:
            _check_known(body, set())
        case FaultKind.ONLINE_CHANGE:
            _check_known(body, {"pdo_groups", "removed"})
            if body.get("pdo_groups") is not None:
                params["pdo_groups"] = _pdo_groups(body["pdo_groups"])
            if body.get("removed") is not None:
                params["removed"] = _slave_names(body["removed"])
        case FaultKind.REFUSE:
            _check_known(body, {"seconds"})
            if "seconds" not in body:
                raise FaultError("refuse needs seconds")
            params["seconds"] = _number(body["seconds"], "seconds")
        case FaultKind.STALL:
            _check_known(body, {"seconds"})
            if body.get("seconds") is not None:
                params["seconds"] = _number(body["seconds"], "seconds")
        case FaultKind.ERROR:
            _check_known(body, {"code", "group", "symbols"})
            if "code" not in body:
                raise FaultError("error needs code (an ADS return code, e.g. 1793)")
            params["code"] = _integer(body["code"], "code", 1, 0xFFFF_FFFF)
            if body.get("group") is not None and body.get("symbols") is not None:
                raise FaultError("give an index group or symbols, not both")
            if body.get("group") is not None:
                params["group"] = _integer(body["group"], "group", 0, 0xFFFF_FFFF)
            if body.get("symbols") is not None:
                params["symbols"] = _symbols(body["symbols"])
        case FaultKind.SLAVE_STATE:
            _check_known(body, {"state", "address", "name", "device"})
            if "state" not in body:
                raise FaultError("slave_state needs state (INIT, PREOP, SAFEOP, OP)")
            params["state"] = _slave_state(body["state"])
            params.update(_optional_slave(body))
        case FaultKind.LINK_LOST:
            _check_known(body, {"lost", "address", "name", "device"})
            lost = body.get("lost", True)
            if not isinstance(lost, bool):
                raise FaultError(f"lost must be true or false, got {lost!r}")
            params["lost"] = lost
            params.update(_optional_slave(body))
    return Fault(kind, params)
