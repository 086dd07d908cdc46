"""Start the simulator as a subprocess on free ports and talk to its control API.

For tests, benchmarks and the demo: the simulator runs in its own process (its
own GIL, like a real PLC), binds every port with port 0, and announces the
ports it got in its ready line, so parallel runs never collide.

    with SimProcess(chain="ioc/demo-chain.yaml") as sim:
        pyads.Connection(sim.net_id, 27905, sim.pyads_ip)
        sim.counters()["total"]
        sim.add_fault("refuse", seconds=2)
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Final, Self
from urllib.parse import quote

from fastcs_ethercat.sim.runner import READY_PREFIX, parse_ready_line

READY_TIMEOUT_SECONDS: Final = 60.0
STOP_TIMEOUT_SECONDS: Final = 10.0
HTTP_TIMEOUT_SECONDS: Final = 30.0


class SimProcessError(RuntimeError):
    """The simulator did not come up, or its control API said no."""


class SimProcess:
    """`fastcs-ethercat sim` in a subprocess, stopped (by PID) on exit."""

    def __init__(
        self,
        chain: Path | str,
        *,
        terminals: Path | str | None = None,
        seed: int | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        udp_port: int = 0,
        control_port: int = 0,
        extra_args: Sequence[str] = (),
        env: dict[str, str] | None = None,
        ready_timeout: float = READY_TIMEOUT_SECONDS,
    ) -> None:
        self.args = [
            sys.executable,
            "-m",
            "fastcs_ethercat.cli.sim",
            "--chain",
            str(chain),
            "--host",
            host,
            "--port",
            str(port),
            "--udp-port",
            str(udp_port),
            "--control-port",
            str(control_port),
            "--exit-with-stdin",
        ]
        if terminals is not None:
            self.args += ["--terminals", str(terminals)]
        if seed is not None:
            self.args += ["--seed", str(seed)]
        self.args += list(extra_args)
        self._env = env
        self._ready_timeout = ready_timeout
        self._process: subprocess.Popen[str] | None = None
        self._log: IO[str] | None = None
        self.fields: dict[str, str] = {}

    # -- life cycle --------------------------------------------------------------

    def start(self) -> None:
        """Start and wait for the ready line (raise with the log if none comes)."""
        self._log = tempfile.TemporaryFile(  # noqa: SIM115 - lives as long as the process
            "w+", prefix="sim-", suffix=".log"
        )
        self._process = subprocess.Popen(
            self.args,
            stdin=subprocess.PIPE,  # closed when we go: the simulator follows
            stdout=subprocess.PIPE,
            stderr=self._log,
            text=True,
            env=self._env,
        )
        lines: list[str] = []
        reader = threading.Thread(
            target=self._read_stdout, args=(self._process, lines), daemon=True
        )
        reader.start()
        deadline = time.monotonic() + self._ready_timeout
        while time.monotonic() < deadline:
            ready = next(
                (line for line in lines if line.startswith(READY_PREFIX)), None
            )
            if ready is not None:
                self.fields = parse_ready_line(ready)
                return
            if self._process.poll() is not None:
                reader.join(1)
                break
            time.sleep(0.02)
        self.stop()
        raise SimProcessError(
            f"simulator did not get ready: {' '.join(self.args)}\n{self.log_text()}"
        )

    @staticmethod
    def _read_stdout(process: subprocess.Popen[str], lines: list[str]) -> None:
        """Keep reading stdout so the simulator never blocks on a full pipe."""
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line.rstrip("\n"))

    def stop(self) -> int | None:
        """SIGTERM (then SIGKILL) by PID; return the exit code."""
        process = self._process
        if process is None:
            return None
        if process.stdin is not None:
            process.stdin.close()
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(STOP_TIMEOUT_SECONDS)
            except subprocess.TimeoutExpired:
                os.kill(process.pid, signal.SIGKILL)
                process.wait(STOP_TIMEOUT_SECONDS)
        return process.returncode

    @property
    def pid(self) -> int:
        assert self._process is not None, "not started"
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        return None if self._process is None else self._process.poll()

    def log_text(self) -> str:
        """What the simulator wrote to stderr so far."""
        if self._log is None:
            return ""
        self._log.flush()
        self._log.seek(0)
        text = self._log.read()
        self._log.seek(0, os.SEEK_END)
        return text

    def __enter__(self) -> Self:
        self.start()
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

    # -- where it listens ----------------------------------------------------------

    @property
    def net_id(self) -> str:
        return self.fields["net_id"]

    @property
    def host(self) -> str:
        return self.fields["tcp"].rsplit(":", 1)[0]

    @property
    def tcp_port(self) -> int:
        return int(self.fields["tcp"].rsplit(":", 1)[1])

    @property
    def udp_port(self) -> int:
        return int(self.fields["udp"].rsplit(":", 1)[1])

    @property
    def control_url(self) -> str:
        return self.fields["control"]

    @property
    def pyads_ip(self) -> str:
        """The `ip_address` for pyads.Connection: AdsLib takes "host:port"."""
        return f"{self.host}:{self.tcp_port}"

    # -- control API ---------------------------------------------------------------

    def request(self, method: str, path: str, body: Any = None) -> Any:
        """One control API call; raise `SimProcessError` on a non-2xx answer."""
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(
            self.control_url + path,
            data=data,
            method=method,
            headers={"Content-Type": "application/json"},
        )
        try:
            with urllib.request.urlopen(
                request, timeout=HTTP_TIMEOUT_SECONDS
            ) as answer:
                return json.loads(answer.read())
        except urllib.error.HTTPError as error:
            detail = error.read().decode(errors="replace").strip()
            raise SimProcessError(f"{method} {path}: {error.code} {detail}") from None

    def counters(self) -> dict[str, Any]:
        return self.request("GET", "/counters")

    def reset_counters(self) -> dict[str, Any]:
        return self.request("DELETE", "/counters")

    def get_symbol(self, name: str) -> Any:
        return self.request("GET", "/symbols/" + quote(name, safe=""))["value"]

    def set_symbol(self, name: str, value: Any) -> Any:
        path = "/symbols/" + quote(name, safe="")
        return self.request("PUT", path, {"value": value})["value"]

    def add_fault(self, kind: str, **params: Any) -> dict[str, Any]:
        return self.request("POST", "/faults", {"kind": kind, **params})

    def clear_faults(self) -> dict[str, Any]:
        return self.request("DELETE", "/faults")

    def status(self) -> dict[str, Any]:
        return self.request("GET", "/status")
