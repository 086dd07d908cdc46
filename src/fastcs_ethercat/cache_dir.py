"""Where fastcs-ethercat keeps what it can compute again: one XDG place."""

from __future__ import annotations

import os
from pathlib import Path

APP_DIR = "fastcs-ethercat"


def cache_dir(kind: str) -> Path:
    """`$XDG_CACHE_HOME/fastcs-ethercat/<kind>` (XDG default `~/.cache`)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / APP_DIR / kind
