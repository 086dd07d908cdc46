"""Where the IOC keeps what must outlive its process, and its heartbeat file.

A container loses its home with the pod: the epics-containers chart gives
each IOC a persistent `/epics/runtime`, which the image names in
`FASTCS_ETHERCAT_RUNTIME_DIR`. Set, it holds the chain cache and the start
count; unset (a development machine), they stay in the XDG cache.

The heartbeat file (`FASTCS_ETHERCAT_HEARTBEAT_FILE`, set by the image) is
what the image's liveness and preStop scripts read: the IOC's PID and the
time of its last 1 s health scan. Unset, none is written.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Final

from fastcs_ethercat.cache_dir import cache_dir

RUNTIME_ENV: Final = "FASTCS_ETHERCAT_RUNTIME_DIR"
HEARTBEAT_ENV: Final = "FASTCS_ETHERCAT_HEARTBEAT_FILE"


def state_dir(kind: str) -> Path:
    """`$FASTCS_ETHERCAT_RUNTIME_DIR/<kind>` if set, else the XDG cache's."""
    runtime = os.environ.get(RUNTIME_ENV)
    return Path(runtime) / kind if runtime else cache_dir(kind)


def heartbeat_file() -> Path | None:
    """The heartbeat file the image's probes read, if one is asked for."""
    path = os.environ.get(HEARTBEAT_ENV)
    return Path(path) if path else None


__all__ = ["HEARTBEAT_ENV", "RUNTIME_ENV", "heartbeat_file", "state_dir"]
