"""Simulated systems of any size, written as chain files into a scratch dir.

Chain files follow `chain/file.py`. Start-up chains repeat the demo system's
mix of terminal types (every type in `terminals/`, dynamic PDOs included);
scan chains are couplers plus EL3104s (36 selected symbols each) whose
inputs either never change or change every poll.
"""

from __future__ import annotations

import itertools
import math
import shutil
from pathlib import Path
from typing import Any, Final

import yaml

SCAN_TYPE: Final = "EL3104"
SCAN_SYMBOLS_PER_TERMINAL: Final = 36
"""4 channels x 9 members of the Standard PDOs, each one selected symbol."""
TERMINALS_PER_COUPLER: Final = 60


def write_chain(
    path: Path, slaves: list[dict[str, Any]], *, task_cycle_ms: float = 10.0
) -> Path:
    """One master with `slaves` in bus order."""
    chain = {
        "system": {"net_id": "127.0.0.1.1.1", "task_cycle_ms": task_cycle_ms},
        "masters": [{"name": "Device 1 (EtherCAT)", "slaves": slaves}],
    }
    path.write_text(yaml.safe_dump(chain, sort_keys=False))
    return path


def demo_mix(demo_chain: Path) -> list[dict[str, Any]]:
    """The demo chain's slaves, without their names (so they can repeat)."""
    chain = yaml.safe_load(demo_chain.read_text())
    slaves = [s for master in chain["masters"] for s in master["slaves"]]
    return [{k: v for k, v in s.items() if k != "name"} for s in slaves]


def mixed_slaves(count: int, mix: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """`count` slaves cycling through `mix`."""
    return [dict(s) for s in itertools.islice(itertools.cycle(mix), count)]


SCAN_CHANNELS: Final = 4
NOISE_AMPLITUDE: Final = 4.0
"""Counts either side of a noisy analog value's level (`scan_slaves(noisy=)`)."""


def scan_slaves(
    symbols: int, *, changing: bool, noisy: bool = False
) -> list[dict[str, Any]]:
    """Enough EL3104s for `symbols` selected symbols, behind couplers.

    Unchanging inputs are constant; changing ones count up every task cycle
    (run the task one cycle per poll, `--cycle-per-poll`, so every poll sees a
    new value, bits too). Noisy ones are constant but for each channel's
    value, which wanders a few counts (`NOISE_AMPLITUDE`) about a level from
    cycle to cycle, as an analog input's low bits do.
    """
    signal = (
        {"kind": "counter", "start": 0, "step": 1}
        if changing
        else {"kind": "constant", "value": 0}
    )
    noise = {"kind": "sine", "offset": 1000, "amplitude": NOISE_AMPLITUDE}
    terminals = math.ceil(symbols / SCAN_SYMBOLS_PER_TERMINAL)
    slaves: list[dict[str, Any]] = []
    for index in range(terminals):
        if index % TERMINALS_PER_COUPLER == 0:
            slaves.append({"type": "EK1100"})
        slave: dict[str, Any] = {
            "type": SCAN_TYPE,
            "pdo_group": "Standard",
            "signal": dict(signal),
        }
        if noisy:
            slave["signals"] = {
                f"AI Standard Channel {channel}.Value": {
                    **noise,
                    "period_s": 0.7 + 0.1 * channel,
                }
                for channel in range(1, SCAN_CHANNELS + 1)
            }
        slaves.append(slave)
    return slaves


def terminals_with_coe(source: Path, target: Path) -> Path:
    """A copy of the terminal YAML directory with every CoE object selected."""
    target.mkdir(parents=True, exist_ok=True)
    for path in source.iterdir():
        if path.suffix not in (".yaml", ".json"):
            continue
        if path.suffix == ".json":
            shutil.copy(path, target / path.name)
            continue
        head, marker, tail = path.read_text().partition("\n  coe_objects:\n")
        tail = tail.replace("    selected: false\n", "    selected: true\n")
        (target / path.name).write_text(head + marker + tail)
    return target
