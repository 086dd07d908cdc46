"""Shared helpers of the simulator model tests (no tests in here).

The terminal YAML is parsed once per test session (it is the slow part);
every test that changes the model builds its own `SimTarget` from it, which
takes milliseconds.
"""

from __future__ import annotations

import functools
import struct
from pathlib import Path
from typing import Final

from fastcs_ethercat.ads.commands import ReadWriteResponse
from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.chain.file import Chain, load_chain, parse_chain
from fastcs_ethercat.sim.probe import ProbeError, SimProbe, device_probe
from fastcs_ethercat.terminals.registry import TerminalRegistry
from fastcs_ethercat.twincat.resolve import registry_for
from fastcs_ethercat.twincat.target import SimTarget

REPO_ROOT: Final = Path(__file__).resolve().parents[1]
TERMINALS_DIR: Final = REPO_ROOT / "terminals"
DEMO_CHAIN: Final = REPO_ROOT / "ioc" / "demo-chain.yaml"
SYSTEM_NET_ID: Final = AmsNetId.parse("127.0.0.1.1.1")
DEVICE_NET_ID: Final = AmsNetId.parse("127.0.0.1.2.1")
MASTER_PORT: Final = 0xFFFF
DEVICE_PORT: Final = 27905

EL3104_COMPACT: Final = "Term 5 (EL3104)"
EL3104_STANDARD: Final = "Term 22 (EL3104)"
EL1502_TWO_COUNTERS: Final = "Term 8 (EL1502)"
EL1014: Final = "Term 2 (EL1014)"
EL2024: Final = "Term 6 (EL2024)"
EL4134: Final = "Term 15 (EL4134)"
EL3702: Final = "Term 14 (EL3702)"


@functools.cache
def registry() -> TerminalRegistry:
    """Every terminal type of the repository, parsed once."""
    return registry_for(TERMINALS_DIR)


@functools.cache
def demo_chain() -> Chain:
    return load_chain(DEMO_CHAIN)


def demo_target(seed: int = 0) -> SimTarget:
    """A fresh target playing `ioc/demo-chain.yaml`."""
    return SimTarget(demo_chain(), registry(), seed)


def target_from_text(text: str, seed: int = 0) -> SimTarget:
    """A fresh target for a chain given as YAML text."""
    return SimTarget(parse_chain(text, "test-chain.yaml"), registry(), seed)


def device(target: SimTarget, number: int = 1) -> SimProbe:
    """A probe on the symbol port of device `number`."""
    return device_probe(target, target.system_net_id, number)


def master(target: SimTarget, net_id: AmsNetId = DEVICE_NET_ID) -> SimProbe:
    return device(target).at(MASTER_PORT, net_id)


def handle_of(probe: SimProbe, name: str) -> int:
    """A handle by name (0xF003); raises on an error result."""
    answer = probe.read_write(
        IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, name.encode("cp1252") + b"\0"
    )
    if answer.result != AdsReturnCode.NO_ERROR:
        raise ProbeError(answer.result)
    return struct.unpack("<I", answer.data)[0]


def value_by_name(probe: SimProbe, name: str, length: int) -> ReadWriteResponse:
    return probe.read_write(
        IndexGroup.SYM_VALUE_BY_NAME, 0, length, name.encode("cp1252") + b"\0"
    )


def info_by_name(probe: SimProbe, name: str, length: int = 1024) -> ReadWriteResponse:
    return probe.read_write(
        IndexGroup.SYM_INFO_BY_NAME_EX, 0, length, name.encode("cp1252") + b"\0"
    )
