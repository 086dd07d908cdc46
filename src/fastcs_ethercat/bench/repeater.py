"""caRepeater: the CA client library starts one if none runs, and it outlives
the client that started it (its parent becomes init). The bench marks its
run's environment with a token every child inherits, the caRepeater too, and
stops the caRepeaters that carry it."""

from __future__ import annotations

import os
import secrets
import signal
from pathlib import Path
from typing import Final

RUN_TOKEN: Final = "FASTCS_ETHERCAT_BENCH_RUN"
"""The environment variable that marks the processes of one bench run."""


def mark_run() -> str:
    """Put a fresh token in this process's environment (children inherit it)."""
    token = secrets.token_hex(8)
    os.environ[RUN_TOKEN] = token
    return token


def _is_repeater_of(pid: int, marker: bytes) -> bool:
    try:
        name = Path(f"/proc/{pid}/comm").read_text().strip()
        if name != "caRepeater":
            return False
        return marker in Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    except OSError:  # gone, or not ours to read
        return False


def repeaters_of_run(token: str) -> list[int]:
    """PIDs of the caRepeaters whose environment carries the run's token."""
    marker = f"{RUN_TOKEN}={token}".encode()
    return [
        int(entry.name)
        for entry in Path("/proc").iterdir()
        if entry.name.isdecimal() and _is_repeater_of(int(entry.name), marker)
    ]


def stop_repeaters_of_run(token: str) -> list[int]:
    """SIGTERM every caRepeater of the run; return their PIDs."""
    stopped = []
    for pid in repeaters_of_run(token):
        try:
            os.kill(pid, signal.SIGTERM)
            stopped.append(pid)
        except ProcessLookupError:
            pass
    return stopped
