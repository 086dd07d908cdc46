"""Run the simulator: AMS/TCP server, UDP discovery, control API and the task
cycle that moves the model and pushes notifications, all in one event loop.

    Simulator(target, SimulatorConfig(...))   start() / stop() inside a loop
    serve(target, config)                     the CLI: ready line, SIGINT/SIGTERM
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final, Protocol

from fastcs_ethercat.ads.constants import ADS_TCP_PORT, ADS_UDP_PORT
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.loopback import LOOPBACK
from fastcs_ethercat.process import ready_line as ready_line_of
from fastcs_ethercat.sim.control import (
    ControlHttpServer,
    ControllableTarget,
    Endpoints,
    SimControl,
)
from fastcs_ethercat.sim.server import AmsServer, SimTargetLike
from fastcs_ethercat.sim.udp import UdpResponder

log = logging.getLogger(__name__)

CONTROL_HOST: Final = LOOPBACK
"""The control API can force values and break things: loopback only, always."""
DEFAULT_CYCLE_SECONDS: Final = 0.010


class RunnableTarget(SimTargetLike, ControllableTarget, Protocol):
    """Everything the simulator asks of the model (`twincat.target.SimTarget`)."""

    @property
    def system_net_id(self) -> AmsNetId: ...

    @property
    def cycle_s(self) -> float:
        """The model's task cycle (the chain's task_cycle_ms), in seconds."""
        ...

    def tick(self, now: float) -> Any: ...


@dataclass(frozen=True)
class SimulatorConfig:
    """Where to listen and how the task cycle runs. Port 0 = any free port;
    `udp_port` / `control_port` None = that service is off. `cycle_per_poll`:
    the task advances one cycle at the first request at least 3/4 of a cycle
    after its last advance, not by the clock, so a client polling once a cycle
    sees exactly one new cycle at every poll whatever the phase between the
    two (benchmarks: on a clock, a poll landing on a tick sees two cycles or
    none, and a bit that toggles every cycle reads the same)."""

    host: str = LOOPBACK
    port: int = ADS_TCP_PORT
    udp_port: int | None = ADS_UDP_PORT
    control_port: int | None = None
    cycle_per_poll: bool = False


def ready_line(endpoints: Endpoints) -> str:
    """The one line the CLI prints when every socket is bound."""
    udp = (
        f"{endpoints.host}:{endpoints.udp_port}"
        if endpoints.udp_port is not None
        else "off"
    )
    control = (
        f"http://{CONTROL_HOST}:{endpoints.control_port}"
        if endpoints.control_port is not None
        else "off"
    )
    tcp = f"{endpoints.host}:{endpoints.tcp_port}"
    return ready_line_of(
        "sim", net_id=endpoints.net_id, tcp=tcp, udp=udp, control=control
    )


class Simulator:
    """One simulated TwinCAT system on loopback sockets, inside a running loop."""

    def __init__(
        self, target: RunnableTarget, config: SimulatorConfig | None = None
    ) -> None:
        self.target = target
        self.config = config or SimulatorConfig()
        self.server = AmsServer(target)
        self.udp: UdpResponder | None = None
        self.http: ControlHttpServer | None = None
        self._control: SimControl | None = None
        self._ticker: asyncio.Task[None] | None = None
        self._paced_clock = 0.0
        self._last_advance = 0.0

    @property
    def control(self) -> SimControl:
        if self._control is None:
            raise RuntimeError("the simulator is not started")
        return self._control

    async def start(self) -> None:
        """Bind every socket and start the task cycle."""
        config = self.config
        loop = asyncio.get_running_loop()
        self._control = SimControl(self.server, self.target, loop, self.endpoints)
        try:
            await self.server.start(config.host, config.port)
            if config.udp_port is not None:
                self.udp = UdpResponder(self.target.system_net_id)
                await self.udp.start(config.host, config.udp_port)
            if config.control_port is not None:
                self.http = ControlHttpServer(self._control)
                await self.http.start(CONTROL_HOST, config.control_port)
        except BaseException:
            await self.stop()
            raise
        if config.cycle_per_poll:
            self._paced_clock = self._last_advance = time.monotonic()
            self.target.tick(self._paced_clock)
            self.server.on_request = self._advance_if_polled
        self._ticker = loop.create_task(self._tick_forever(), name="sim-task-cycle")

    @property
    def period(self) -> float:
        """The task cycle, in seconds."""
        return self.target.cycle_s or DEFAULT_CYCLE_SECONDS

    def _advance_if_polled(self) -> None:
        """`cycle_per_poll`: one cycle on the first request of a new poll."""
        now = time.monotonic()
        if now - self._last_advance >= 0.75 * self.period:
            self._last_advance = now
            self._paced_clock += self.period
            self.target.tick(self._paced_clock)

    async def stop(self) -> None:
        """Close every socket and stop the task cycle (idempotent)."""
        if self._ticker is not None:
            self._ticker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._ticker
            self._ticker = None
        if self.http is not None:
            await self.http.close()
            self.http = None
        if self.udp is not None:
            self.udp.close()
            self.udp = None
        await self.server.close()

    def endpoints(self) -> Endpoints:
        return Endpoints(
            net_id=str(self.target.system_net_id),
            host=self.config.host,
            tcp_port=self.server.port,
            udp_port=self.udp.port if self.udp is not None else None,
            control_port=self.http.port if self.http is not None else None,
        )

    def ready_line(self) -> str:
        return ready_line(self.endpoints())

    async def _tick_forever(self) -> None:
        """The task cycle: move the model, then push due notifications."""
        loop = asyncio.get_running_loop()
        period = self.period
        deadline = loop.time()
        while True:
            try:
                if not self.config.cycle_per_poll:
                    self.target.tick(time.monotonic())
                now_ns = time.monotonic_ns()
                self.server.tick(now_ns, time.time_ns(), now_ns + int(period * 1e9))
            except Exception:
                log.exception("task cycle failed")
            deadline += period
            delay = deadline - loop.time()
            if delay < 0:  # overran: skip the missed cycles instead of bursting
                deadline = loop.time()
                delay = 0
            await asyncio.sleep(delay)


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""What stops the simulator cleanly (SIGHUP: its terminal closed)."""


async def serve(
    target: RunnableTarget,
    config: SimulatorConfig,
    *,
    announce: Callable[[str], None] = lambda line: print(line, flush=True),
    exit_with_stdin: bool = False,
) -> None:
    """Run until SIGINT, SIGTERM or SIGHUP; announce the ready line once bound.

    With `exit_with_stdin`, also stop when stdin reaches end of file: a parent
    that holds our stdin pipe (`SimProcess`) takes us down when it dies, even
    if it never got to send a signal.
    """
    simulator = Simulator(target, config)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for signum in STOP_SIGNALS:
        loop.add_signal_handler(signum, stop.set)
    stdin = sys.stdin.fileno() if exit_with_stdin else None
    if stdin is not None:
        loop.add_reader(stdin, _stop_at_eof, stdin, stop)
    try:
        await simulator.start()
        announce(simulator.ready_line())
        await stop.wait()
    finally:
        if stdin is not None:
            loop.remove_reader(stdin)
        for signum in STOP_SIGNALS:
            loop.remove_signal_handler(signum)
        await simulator.stop()


def _stop_at_eof(fd: int, stop: asyncio.Event) -> None:
    try:
        data = os.read(fd, 4096)
    except OSError:
        data = b""
    if not data:
        stop.set()
