"""caRepeater: the CA client library starts one if none runs; stop ours."""

from __future__ import annotations

import os
import signal
from pathlib import Path


def _name_and_parent(pid: int) -> tuple[str, int] | None:
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    name = text[text.index("(") + 1 : text.rindex(")")]
    parent = int(text.rsplit(")", 1)[1].split()[1])
    return name, parent


def repeaters_of(parent: int) -> list[int]:
    """PIDs of caRepeater processes whose parent is `parent`."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdecimal():
            continue
        info = _name_and_parent(int(entry.name))
        if info is not None and info == ("caRepeater", parent):
            found.append(int(entry.name))
    return found


def stop_own_repeaters() -> list[int]:
    """SIGTERM every caRepeater this process started; return their PIDs."""
    stopped = []
    for pid in repeaters_of(os.getpid()):
        try:
            os.kill(pid, signal.SIGTERM)
            stopped.append(pid)
        except ProcessLookupError:
            pass
    return stopped
