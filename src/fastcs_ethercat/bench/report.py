"""The JSON document and the printed summary, with the issue's targets."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

REQUIRED_KEYS = (
    "esi_catalog_s",
    "terminals_regenerate_s",
    "ioc_start_s",
    "scan",
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
    lines = [
        f"machine: {document['machine']['cores']} cores,"
        f" {document['machine']['cpu_model']}",
        f"ESI catalog (cold):        {_figure(document['esi_catalog_s'], ' s')}",
        "terminals regenerate:      "
        + _figure(document["terminals_regenerate_s"], " s"),
    ]
    for key, label in (("ioc_start_s", "IOC start"), ("ioc_start_coe_s", "  + CoE")):
        for size, value in _items(document.get(key)):
            ok = value < 3.0 if size == "104" and key == "ioc_start_s" else None
            lines.append(
                f"{label} {size:>4} terminals: {_figure(value, ' s')}"
                + (_verdict(ok) if isinstance(value, float) else "")
            )
    for size, value in _items(document.get("rss_mb")):
        lines.append(f"peak RSS {size:>4} terminals: {_figure(value, ' MB')}")
    for entry in document.get("scan", []):
        if "error" in entry:
            target = entry.get("target_symbols")
            lines.append(f"scan ~{target} symbols: ERROR {entry['error']}")
            continue
        big = entry["symbols"] >= 10000
        lines.append(
            f"scan {entry['symbols']} symbols @10 Hz: "
            f"{entry['requests_per_cycle']} req/cycle"
            + _verdict(entry["requests_per_cycle"] <= 20 if big else None)
            + f", CPU {entry['cpu_unchanged_pct']}% unchanged"
            + _verdict(entry["cpu_unchanged_pct"] < 25 if big else None)
            + f" / {entry['cpu_changing_pct']}% changing"
            + f", {entry['updates_per_s']} updates/s received"
            + _verdict(entry["updates_per_s"] >= 10000 if big else None)
        )
    for rate, value in _items(document.get("latency_ms")):
        if isinstance(value, dict) and "p99" in value:
            ok = value["p99"] < 1.5 * value["poll_period_ms"]
            lines.append(
                f"latency @{rate} Hz: p50 {value['p50']} ms, p99 {value['p99']} ms"
                + _verdict(ok)
            )
        else:
            lines.append(f"latency @{rate} Hz: {_figure(value)}")
    return lines


def _items(section: Any) -> list[tuple[str, Any]]:
    if isinstance(section, dict) and not ({"error", "skipped"} & section.keys()):
        return list(section.items())
    return [("all", section)] if section is not None else []
