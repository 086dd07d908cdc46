"""`fastcs-ethercat ioc` as a subprocess on loopback, stopped by PID."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Final, Self

import yaml

from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV

READY_PREFIX: Final = "fastcs-ethercat ioc ready:"
STOP_TIMEOUT_S: Final = 10.0


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
    """The IOC exited or did not say it was ready in time."""


def loopback_env() -> dict[str, str]:
    return {**os.environ, **EPICS_LOOPBACK_ENV}


def write_ioc_config(
    path: Path, *, prefix: str, terminals: Path, poll_rate_hz: float
) -> Path:
    """An IOC instance file (see `ioc/config.py`); target comes by flag."""
    config = {
        "prefix": prefix,
        "target": "127.0.0.1:48898",
        "poll_rate_hz": poll_rate_hz,
        "terminal_dirs": [str(terminals.resolve())],
        "transports": {"ca": True, "pva": True},
    }
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


class IocProcess:
    """The IOC serving a target; `started_at`/`ready_at` are monotonic times."""

    def __init__(self, config: Path, target: str, net_id: str) -> None:
        self.args = ioc_args(config, target, net_id)
        self._process: subprocess.Popen[str] | None = None
        self._log: IO[str] | None = None
        self._lines: list[str] = []
        self.started_at = 0.0
        self.ready_at: float | None = None

    def start(self, timeout: float) -> None:
        """Start and wait for the ready line."""
        self._log = tempfile.TemporaryFile(  # noqa: SIM115 - lives with the process
            "w+", prefix="ioc-", suffix=".log"
        )
        self.started_at = time.monotonic()
        self._process = subprocess.Popen(
            self.args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._log,
            text=True,
            env=loopback_env(),
        )
        threading.Thread(target=self._read_stdout, daemon=True).start()
        deadline = self.started_at + timeout
        while time.monotonic() < deadline:
            if self.ready_at is not None:
                return
            if self._process.poll() is not None:
                break
            time.sleep(0.005)
        self.stop()
        raise IocProcessError(f"IOC not ready: {self.log_tail()}")

    def _read_stdout(self) -> None:
        process = self._process
        assert process is not None and process.stdout is not None
        for line in process.stdout:
            if line.startswith(READY_PREFIX) and self.ready_at is None:
                self.ready_at = time.monotonic()
            self._lines.append(line.rstrip("\n"))

    @property
    def pid(self) -> int:
        assert self._process is not None, "not started"
        return self._process.pid

    def alive(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def log_tail(self, chars: int = 800) -> str:
        if self._log is None:
            return "\n".join(self._lines)[-chars:]
        self._log.flush()
        self._log.seek(0)
        text = self._log.read()
        self._log.seek(0, os.SEEK_END)
        return (text + "\n".join(self._lines)).strip()[-chars:]

    def stop(self) -> None:
        """SIGTERM, then SIGKILL, by PID."""
        process = self._process
        if process is None:
            return
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                os.kill(process.pid, signal.SIGKILL)
                process.wait(STOP_TIMEOUT_S)

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()
        if self._log is not None:
            self._log.close()
            self._log = None
