"""`fastcs-ethercat ioc` as a subprocess on loopback, stopped by PID."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import yaml

from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV
from fastcs_ethercat.process import ChildProcess

_LIST_WITHOUT_SIGINT: Final = (
    "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN); "
    "sys.argv[0] = 'fastcs-ethercat'; "
    "runpy.run_module('fastcs_ethercat', run_name='__main__', alter_sys=True)"
)
"""`fastcs-ethercat ...` with SIGINT ignored (nobody interrupts a listing).
Python 3.11's `asyncio.run` then installs no SIGINT handler, and does not
format the repr of its main task (with the whole result) when restoring it,
which costs seconds to minutes for a big IOC."""


class IocProcessError(RuntimeError):
    """`ioc --list-pvs` failed or took too long."""


def loopback_env() -> dict[str, str]:
    return {**os.environ, **EPICS_LOOPBACK_ENV}


def write_ioc_config(
    path: Path,
    *,
    prefix: str,
    terminals: Path,
    poll_rate_hz: float,
    deadbands: dict[str, float] | None = None,
    chain: Path | None = None,
) -> Path:
    """An IOC instance file (see `ioc/config.py`); target comes by flag;
    `chain`: what it serves while the target does not answer."""
    config: dict[str, object] = {
        "prefix": prefix,
        "target": "127.0.0.1:48898",
        "poll_rate_hz": poll_rate_hz,
        "terminal_dirs": [str(terminals.resolve())],
        "transports": {"ca": True, "pva": True},
    }
    if deadbands:
        config["deadbands"] = deadbands
    if chain is not None:
        config["chain"] = str(chain.resolve())
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


def ioc_args(config: Path, target: str, net_id: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "fastcs_ethercat",
        "ioc",
        "--config",
        str(config),
        "--target",
        target,
        "--ams-net-id",
        net_id,
    ]


@dataclass(frozen=True, slots=True)
class PvLine:
    """One line of `--list-pvs`: NAME ACCESS TYPE SOURCE."""

    name: str
    access: str
    type: str
    source: str

    @property
    def is_symbol(self) -> bool:
        """A PV fed by a polled symbol (not the IOC's own, not a CoE object)."""
        return self.source != "ioc" and not self.source.lower().startswith("coe")


def list_pvs(config: Path, target: str, net_id: str, timeout: float) -> list[PvLine]:
    """Every PV the IOC would serve (connects and discovers, serves nothing)."""
    python, _, _, *rest = ioc_args(config, target, net_id)
    try:
        done = subprocess.run(
            [python, "-c", _LIST_WITHOUT_SIGINT, *rest, "--list-pvs"],
            capture_output=True,
            text=True,
            env=loopback_env(),
            timeout=timeout,
            check=False,
        )
    except subprocess.TimeoutExpired:
        raise IocProcessError(f"ioc --list-pvs took over {timeout:g} s") from None
    if done.returncode != 0:
        raise IocProcessError(f"ioc --list-pvs failed: {done.stderr.strip()[-500:]}")
    lines = []
    for text in done.stdout.splitlines():
        parts = text.split(" ", 3)
        if len(parts) == 4:
            lines.append(PvLine(*parts))
    return lines


class IocProcess(ChildProcess):
    """`fastcs-ethercat ioc` serving a target, on the loopback EPICS settings."""

    def __init__(self, config: Path, target: str, net_id: str) -> None:
        super().__init__(ioc_args(config, target, net_id), "ioc", env=loopback_env())
