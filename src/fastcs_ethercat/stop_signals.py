"""SIGTERM and SIGHUP stop every command cleanly: exit 0, no traceback.

A command runs with SIGTERM raising `Stopped` (a BaseException, so no
`except Exception` swallows it; the CLI turns it into exit 0) and SIGHUP,
which a closing terminal sends, doing what SIGTERM does. A command serving
on an event loop (the IOC through FastCS, the simulator, the editor through
uvicorn) sets its own SIGTERM handler for a graceful stop while it serves;
SIGHUP then reaches that handler too, because it re-raises SIGTERM.
"""

from __future__ import annotations

import signal
from types import FrameType


class Stopped(BaseException):
    """The process was asked to stop (SIGTERM or SIGHUP)."""


def _stop(signum: int, frame: FrameType | None) -> None:
    raise Stopped(signal.Signals(signum).name)


def _as_sigterm(signum: int, frame: FrameType | None) -> None:
    signal.raise_signal(signal.SIGTERM)


def install() -> None:
    """Set the handlers (main thread, once, before the command runs)."""
    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGHUP, _as_sigterm)
