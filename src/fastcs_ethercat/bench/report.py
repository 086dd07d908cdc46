"""The JSON document and the printed summary, with the issue's targets."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

REQUIRED_KEYS = (
    "esi_catalog_s",
    "esi_full_parse_ratio",
    "terminals_regenerate_s",
    "ioc_start_s",
    "scan",
    "scan_deadband",
    "latency_ms",
    "rss_mb",
    "machine",
)
SCAN_KEYS = (
    "symbols",
    "requests_per_cycle",
    "cpu_unchanged_pct",
    "cpu_changing_pct",
    "updates_per_s",
)
START_TARGET_S = 2.5
"""IOC start, 104 terminals, launch to every PV connectable: a start of up
to 2.5 s is fine once every value is processed by record support (issue 24)."""
RSS_TARGETS_MB = {"20": 150.0, "104": 200.0}
CPU_CHANGING_TARGET_PCT = 20.0
"""~1 000 symbols changing every cycle, one client monitoring all (issue 16)."""
SMALL_SCAN_SYMBOLS = 2_000
"""A scan below this many symbols is the ~1 000 case of the CPU target; the
~5 000 case of the full run has no target of its own."""
BIG_SCAN_SYMBOLS = 10_000
"""A scan of at least this many symbols is the ~10 000 case of the rate target."""
UPDATES_TARGET_PER_S = 100_000.0
"""~10 000 symbols changing every cycle: updates one CA client receives on a
quiet machine, every value processed by EPICS's record support (issue 24)."""
LOSS_TARGET_S = 1.0
"""A lost target to every PV INVALID with COMM (issue 5)."""
RECOVERY_TARGET_S = 5.0
"""The target back to PVs valid and updating (issue 5)."""
SLAVE_ALARM_TARGET_S = 2.5
"""One slave out of OP, or its link lost, to its PVs INVALID: the master's
diagnostics are read once a second."""
SLAVE_BACK_TARGET_S = 3.0
"""That slave back in OP to its PVs valid again."""
PDO_CHANGE_TARGET_S = 2.0
"""An online change that takes a slave's PDOs away to their PVs INVALID."""
FAULT_TARGETS_S = {
    "slave_preop": (SLAVE_ALARM_TARGET_S, SLAVE_BACK_TARGET_S),
    "link_lost": (SLAVE_ALARM_TARGET_S, RECOVERY_TARGET_S),
    "pdo_change": (PDO_CHANGE_TARGET_S, RECOVERY_TARGET_S),
}
"""(INVALID, valid again) targets of the faults other than a lost target."""
LIVE_TARGET_S = 5.0
"""An IOC started without its PLC: live values after the PLC appears (issue 11)."""
ESI_RATIO_TARGET = 1.5
"""Full parse of every device against a plain lxml parse of the same files."""


def write_json(document: dict[str, Any], path: Path) -> None:
    path.write_text(json.dumps(document, indent=2) + "\n")


def _figure(value: Any, unit: str = "") -> str:
    if isinstance(value, dict) and "error" in value:
        return f"ERROR {value['error']}"
    if isinstance(value, dict) and "skipped" in value:
        return "skipped"
    if value is None:
        return "-"
    return f"{value}{unit}"


def _verdict(ok: bool | None) -> str:
    return "" if ok is None else ("  [target met]" if ok else "  [target MISSED]")


def summary_lines(document: dict[str, Any]) -> list[str]:
    """Human-readable figures, each against its target where there is one."""
    ratio: Any = document.get("esi_full_parse_ratio")
    lines = [
        f"machine: {document['machine']['cores']} cores,"
        f" {document['machine']['cpu_model']}",
        f"ESI catalog (cold):        {_figure(document['esi_catalog_s'], ' s')}",
        f"ESI full parse / lxml:     {_figure(ratio, 'x')}"
        + (_verdict(float(ratio) <= ESI_RATIO_TARGET) if _is_number(ratio) else ""),
        "terminals regenerate:      "
        + _figure(document["terminals_regenerate_s"], " s"),
    ]
    for key, label in (("ioc_start_s", "IOC start"), ("ioc_start_coe_s", "  + CoE")):
        for size, value in _items(document.get(key)):
            ok = (
                value <= START_TARGET_S
                if size == "104" and key == "ioc_start_s"
                else None
            )
            lines.append(
                f"{label} {size:>4} terminals: {_figure(value, ' s')}"
                + (_verdict(ok) if _is_number(value) else "")
            )
    for size, value in _items(document.get("rss_mb")):
        target = RSS_TARGETS_MB.get(size)
        ok = value <= target if target is not None and _is_number(value) else None
        lines.append(
            f"peak RSS {size:>4} terminals: {_figure(value, ' MB')}" + _verdict(ok)
        )
    lines += [scan_line(entry) for entry in document.get("scan", [])]
    deadband = document.get("scan_deadband")
    if isinstance(deadband, dict) and "updates_per_s_with" in deadband:
        lines.append(
            f"deadband {deadband['deadband']} on {deadband['symbols']} symbols with"
            f" {deadband['noise_counts']}-count noise: updates/s"
            f" {deadband['updates_per_s_without']} -> {deadband['updates_per_s_with']},"
            f" CPU {deadband['cpu_without']}% -> {deadband['cpu_with']}%"
        )
    elif deadband is not None:
        lines.append(f"deadband: {_figure(deadband)}")
    for rate, value in _items(document.get("latency_ms")):
        if isinstance(value, dict) and "p99" in value:
            ok = value["p99"] < 1.5 * value["poll_period_ms"]
            lines.append(
                f"latency @{rate} Hz: p50 {value['p50']} ms, p99 {value['p99']} ms"
                + _verdict(ok)
            )
        else:
            lines.append(f"latency @{rate} Hz: {_figure(value)}")
    return lines + fault_lines(document.get("faults"))


def fault_lines(faults: Any) -> list[str]:
    """Loss and recovery per fault, live values once the PLC appears."""
    if not isinstance(faults, dict) or {"error", "skipped"} & faults.keys():
        return [] if faults is None else [f"faults: {_figure(faults)}"]
    lines = []
    for kind, value in faults.items():
        if kind == "plc_appears":
            live = _seconds(value.get("live_s"), LIVE_TARGET_S)
            lines.append(f"PLC appears after start: live in {live}")
        else:
            loss_target, back_target = FAULT_TARGETS_S.get(
                kind, (LOSS_TARGET_S, RECOVERY_TARGET_S)
            )
            loss = _seconds(value.get("loss_s"), loss_target)
            back = _seconds(value.get("recovery_s"), back_target)
            lines.append(f"fault {kind}: INVALID in {loss}, valid again in {back}")
    return lines


def _seconds(value: Any, target: float) -> str:
    """A duration and its verdict against `target` (at most)."""
    if isinstance(value, int | float):
        return f"{value} s" + _verdict(value <= target)
    return _figure(value)


def scan_line(entry: dict[str, Any]) -> str:
    """One scan's figures, each against the target of its size."""
    if "error" in entry:
        return f"scan ~{entry.get('target_symbols')} symbols: ERROR {entry['error']}"
    big = entry["symbols"] >= BIG_SCAN_SYMBOLS
    small = entry["symbols"] < SMALL_SCAN_SYMBOLS
    changing, received = entry["cpu_changing_pct"], entry["updates_per_s"]
    lost = entry.get("updates_lost_per_s")
    return (
        f"scan {entry['symbols']} symbols @10 Hz: "
        f"{entry['requests_per_cycle']} req/cycle"
        + _verdict(entry["requests_per_cycle"] <= 20 if big else None)
        + f", CPU {entry['cpu_unchanged_pct']}% unchanged"
        + _verdict(entry["cpu_unchanged_pct"] < 25 if big else None)
        + f" / {changing}% changing with {entry.get('client', 'a')} monitoring"
        + _verdict(changing <= CPU_CHANGING_TARGET_PCT if small else None)
        + f" ({entry.get('cpu_changing_no_client_pct', '-')}% unmonitored)"
        + f", {received} updates/s received"
        + _verdict(received >= UPDATES_TARGET_PER_S if big else None)
        + (f", {lost} lost/s" if lost is not None else "")
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _items(section: Any) -> list[tuple[str, Any]]:
    if isinstance(section, dict) and not ({"error", "skipped"} & section.keys()):
        return list(section.items())
    return [("all", section)] if section is not None else []
