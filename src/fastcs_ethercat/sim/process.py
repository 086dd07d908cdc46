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
import sys
import urllib.error
import urllib.request
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final, Self
from urllib.parse import quote

from fastcs_ethercat.loopback import LOOPBACK
from fastcs_ethercat.process import ChildProcess, NotReadyError

READY_TIMEOUT_SECONDS: Final = 60.0
HTTP_TIMEOUT_SECONDS: Final = 30.0


class SimProcessError(RuntimeError):
    """The simulator did not come up, or its control API said no."""


class SimProcess(ChildProcess):
    """`fastcs-ethercat sim` in a subprocess; a `with` block starts it and
    stops it (by PID). Its stdin is held: the simulator exits when we go."""

    def __init__(
        self,
        chain: Path | str,
        *,
        terminals: Path | str | None = None,
        revisions: Sequence[Path | str] = (),
        seed: int | None = None,
        host: str = LOOPBACK,
        port: int = 0,
        udp_port: int = 0,
        control_port: int = 0,
        extra_args: Sequence[str] = (),
        env: dict[str, str] | None = None,
        ready_timeout: float = READY_TIMEOUT_SECONDS,
    ) -> None:
        args = [
            sys.executable,
            "-m",
            "fastcs_ethercat.cli.sim_main",
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
            args += ["--terminals", str(terminals)]
        for source in revisions:
            args += ["--revisions", str(source)]
        if seed is not None:
            args += ["--seed", str(seed)]
        super().__init__([*args, *extra_args], "sim", env=env, stdin_pipe=True)
        self.ready_timeout = ready_timeout

    def start(self, timeout: float | None = None) -> dict[str, str]:
        """Start and wait for the ready line (`SimProcessError` with the log if
        none comes within `timeout`, default `ready_timeout`)."""
        try:
            return super().start(self.ready_timeout if timeout is None else timeout)
        except NotReadyError as error:
            raise SimProcessError(str(error)) from None

    def __enter__(self) -> Self:
        self.start()
        return self

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
