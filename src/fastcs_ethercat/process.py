"""Child processes that announce they are ready, stopped by PID.

The simulator and the IOC each print one ready line once they serve:

    fastcs-ethercat sim ready: net_id=127.0.0.1.1.1 tcp=127.0.0.1:40123 ...
    fastcs-ethercat ioc ready: prefix=DEMO

`ready_line` writes one, `parse_ready_line` reads one, and `ChildProcess`
starts a command, keeps reading its output (so it never blocks on a full
pipe), waits for its ready line and stops it (SIGTERM, then SIGKILL) by PID.
The simulator (`sim.process`), the benchmarks, the demo and the tests all use
these, so there is one protocol and one way to launch; `free_port` gives
them the loopback ports they serve on (and the editor its port on the host
it is told).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from typing import IO, Final, Self

from fastcs_ethercat.loopback import LOOPBACK

READY_FORMAT: Final = "fastcs-ethercat {kind} ready:"
STOP_TIMEOUT_S: Final = 10.0


def ready_prefix(kind: str) -> str:
    """`fastcs-ethercat <kind> ready:` (kind: "sim" or "ioc")."""
    return READY_FORMAT.format(kind=kind)


def ready_line(kind: str, **fields: object) -> str:
    """The one line a `kind` process prints when it serves."""
    words = " ".join(f"{key}={value}" for key, value in fields.items())
    return f"{ready_prefix(kind)} {words}"


def parse_ready_line(line: str, kind: str) -> dict[str, str] | None:
    """The key=value fields of a `kind` ready line, None for any other line."""
    prefix = ready_prefix(kind)
    if not line.startswith(prefix):
        return None
    words = line[len(prefix) :].split()
    return dict(word.split("=", 1) for word in words if "=" in word)


class NotReadyError(RuntimeError):
    """The process exited, or did not print its ready line in time."""


class ChildProcess:
    """A command whose stdout lines are kept and whose stderr goes to a
    temporary file; `started_at`/`ready_at` are `time.monotonic()` times."""

    def __init__(
        self,
        args: Sequence[str],
        kind: str,
        *,
        env: Mapping[str, str] | None = None,
        stdin_pipe: bool = False,
        merge_stderr: bool = False,
    ) -> None:
        self.args = list(args)
        self.kind = kind
        self.env = dict(env) if env is not None else None
        self.stdin_pipe = stdin_pipe
        """Hold the child's stdin: a child that exits at EOF follows us."""
        self.stdin: IO[str] | None = None
        """The child's stdin when held: what is written reaches the child;
        closed at `stop` (EOF)."""
        self.merge_stderr = merge_stderr
        """stderr into `lines` with stdout, in order (tests that read the
        log), not into a temporary file."""
        self.lines: list[str] = []
        self.fields: dict[str, str] = {}
        self.started_at = 0.0
        self.ready_at: float | None = None
        self._process: subprocess.Popen[str] | None = None
        self._log: IO[str] | None = None
        self._reader: threading.Thread | None = None

    def launch(self) -> None:
        """Start, reading its output from now on; `start` also waits."""
        if not self.merge_stderr:
            self._log = tempfile.TemporaryFile(  # noqa: SIM115 - lives with it
                "w+", prefix=f"{self.kind}-", suffix=".log"
            )
        self.started_at = time.monotonic()
        self._process = subprocess.Popen(
            self.args,
            stdin=subprocess.PIPE if self.stdin_pipe else subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT if self.merge_stderr else self._log,
            text=True,
            env=self.env,
        )
        self.stdin = self._process.stdin
        self._reader = threading.Thread(target=self._read_stdout, daemon=True)
        self._reader.start()

    def start(self, timeout: float) -> dict[str, str]:
        """Start and wait for the ready line; its fields (raise with the log)."""
        self.launch()
        assert self._process is not None and self._reader is not None
        deadline = self.started_at + timeout
        while time.monotonic() < deadline:
            if self.ready_at is not None:
                return self.fields
            if self._process.poll() is not None:
                self._reader.join(1)
                if self.ready_at is not None:
                    return self.fields
                break
            time.sleep(0.005)
        self.stop()
        raise NotReadyError(
            f"{self.kind} did not get ready: {' '.join(self.args)}\n{self.log_tail()}"
        )

    def _read_stdout(self) -> None:
        process = self._process
        assert process is not None and process.stdout is not None
        for raw in process.stdout:
            line = raw.rstrip("\n")
            if self.ready_at is None:
                fields = parse_ready_line(line, self.kind)
                if fields is not None:
                    self.fields = fields
                    self.ready_at = time.monotonic()
            self.lines.append(line)

    @property
    def pid(self) -> int:
        assert self._process is not None, "not started"
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        return None if self._process is None else self._process.poll()

    def wait(self, timeout: float) -> int:
        """The exit code, once the process has exited (TimeoutExpired if not)
        and its output is all in `lines`."""
        assert self._process is not None, "not started"
        code = self._process.wait(timeout)
        if self._reader is not None:
            self._reader.join(timeout)
        return code

    def stderr_text(self) -> str:
        """What the process wrote to stderr so far."""
        if self._log is None:
            return ""
        self._log.flush()
        self._log.seek(0)
        text = self._log.read()
        self._log.seek(0, os.SEEK_END)
        return text

    def log_tail(self, chars: int = 800) -> str:
        """The end of stderr and stdout, for an error message."""
        return (self.stderr_text() + "\n".join(self.lines)).strip()[-chars:]

    def stop(self) -> int | None:
        """SIGTERM, then SIGKILL, by PID; the exit code."""
        process = self._process
        if process is None:
            return None
        if self.stdin is not None:
            self.stdin.close()
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                os.kill(process.pid, signal.SIGKILL)
                process.wait(STOP_TIMEOUT_S)
        return process.returncode

    def close(self) -> None:
        """Stop, and drop the log."""
        self.stop()
        if self._log is not None:
            self._log.close()
            self._log = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def free_port(*, tcp: bool, udp: bool, host: str = LOOPBACK) -> int:
    """A port of `host` (loopback unless told) free right now for TCP and/or
    UDP: for a child to serve on, or a server that is told `--port 0`."""
    for _ in range(100):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            probe.bind((host, 0))
            port = int(probe.getsockname()[1])
        kinds = [socket.SOCK_STREAM] * tcp + [socket.SOCK_DGRAM] * udp
        with contextlib.ExitStack() as held:
            try:
                for kind in kinds:
                    sock = held.enter_context(socket.socket(socket.AF_INET, kind))
                    sock.bind((host, port))
            except OSError:
                continue
        return port
    raise OSError(f"no free port on {host}")
