"""The IOC's heartbeat and start count, as devIocStats gives a C IOC.

`HEARTBEAT` counts the root's 1 s health scans: it moves while the IOC's
event loop runs (FastCS's scans, softioc's puts), whether or not the PLC
answers. Each beat also rewrites the heartbeat file (`runtime.heartbeat_file`,
"PID COUNT UNIX-TIME"), which the image's liveness script reads: a file that
stops changing is an IOC that stopped serving.

The file is written from the moment the IOC starts to look for its chain,
before there is a scan to beat: while it waits for a PLC that is away (no
`chain:` and no chain kept from an earlier start) `keep_fresh` rewrites it
every `WAITING_PERIOD_S`, the count at 0, so the liveness probe passes (a
PLC away is an alarm, not a restart) and the preStop script finds the PID.

`START_CNT` counts the starts with one state folder (`runtime.state_dir`: in
the image the chart's persistent /epics/runtime), where devIocStats counts
through autosave.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from fastcs_ethercat.runtime import heartbeat_file, state_dir

logger = logging.getLogger(__name__)

HEARTBEAT_MAX: Final = 2**31 - 1
"""Where the count wraps to 1 (a longin), as devIocStats' HEARTBEAT does."""
START_COUNT_FILE: Final = "start-count"
WAITING_PERIOD_S: Final = 1.0
"""How often the file is rewritten before the health scan beats."""


@dataclass
class Heartbeat:
    """Counts beats and, if asked, writes each to the heartbeat file."""

    path: Path | None = field(default_factory=heartbeat_file)
    count: int = 0
    _fresh: asyncio.Task[None] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self._write()  # the PID, for the preStop script, before the first beat

    def beat(self) -> int:
        self.count = self.count + 1 if self.count < HEARTBEAT_MAX else 1
        self._write()
        return self.count

    def keep_fresh(self) -> None:
        """Rewrite the file every `WAITING_PERIOD_S` on the running loop, the
        count unchanged, until `stop_keeping_fresh` (the scan beats then)."""
        if self._fresh is None and self.path is not None:
            self._fresh = asyncio.get_running_loop().create_task(self._rewrite())

    def stop_keeping_fresh(self) -> None:
        if self._fresh is not None:
            self._fresh.cancel()
            self._fresh = None

    async def _rewrite(self) -> None:
        with contextlib.suppress(asyncio.CancelledError):
            while self.path is not None:
                await asyncio.sleep(WAITING_PERIOD_S)
                self._write()

    def _write(self) -> None:
        if self.path is None:
            return
        text = f"{os.getpid()} {self.count} {time.time():.3f}\n"
        temporary = self.path.with_name(f".{self.path.name}.{os.getpid()}")
        try:
            temporary.write_text(text, encoding="ascii")
            os.replace(temporary, self.path)  # the probe never reads half a line
        except OSError as error:
            logger.warning("cannot write the heartbeat file %s: %s", self.path, error)
            self.path = None  # once: the PVs still beat


def count_start(folder: Path | None = None) -> int:
    """This start's number (1 the first time), kept in `folder`; 0 where it
    cannot be kept (a read-only folder costs a warning, never the IOC)."""
    path = (folder or state_dir("ioc")) / START_COUNT_FILE
    try:
        previous = int(path.read_text(encoding="ascii").strip() or 0)
    except FileNotFoundError:
        previous = 0
    except (OSError, ValueError) as error:
        logger.warning(
            "start count unreadable in %s (%s): counting from 1", path, error
        )
        previous = 0
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"{previous + 1}\n", encoding="ascii")
    except OSError as error:
        logger.warning("cannot keep the start count in %s: %s", path, error)
        return 0
    return previous + 1


__all__ = ["Heartbeat", "count_start"]
