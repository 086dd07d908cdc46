"""The simulator on a thread of its own, for in-process tests whose client
blocks (pyads): the test thread stays free to block while it answers."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Any, Final, Self

from fastcs_ethercat.sim.control import SimControl
from fastcs_ethercat.sim.runner import (
    Endpoints,
    RunnableTarget,
    Simulator,
    SimulatorConfig,
)

THREAD_START_TIMEOUT_SECONDS: Final = 30.0


class SimulatorThread:
    """A `Simulator` on its own event loop in a daemon thread.

    with SimulatorThread(target, SimulatorConfig(port=0, udp_port=0)) as sim:
        sim.endpoints.tcp_port, sim.control.counters()
    """

    def __init__(
        self, target: RunnableTarget, config: SimulatorConfig | None = None
    ) -> None:
        self.simulator = Simulator(
            target, config or SimulatorConfig(port=0, udp_port=0)
        )
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, name="simulator", daemon=True)
        self._started = threading.Event()
        self._stop: asyncio.Event | None = None
        self._error: BaseException | None = None

    @property
    def control(self) -> SimControl:
        return self.simulator.control

    @property
    def endpoints(self) -> Endpoints:
        return self.simulator.endpoints()

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        return self._loop

    def call(self, function: Callable[[], Any]) -> Any:
        """Run `function` on the simulator's loop and return its result."""
        future = asyncio.run_coroutine_threadsafe(_as_coroutine(function), self._loop)
        return future.result(timeout=THREAD_START_TIMEOUT_SECONDS)

    def start(self) -> None:
        self._thread.start()
        if not self._started.wait(THREAD_START_TIMEOUT_SECONDS):
            raise RuntimeError("the simulator thread did not start")
        if self._error is not None:
            self._thread.join()
            raise self._error

    def stop(self) -> None:
        if self._thread.is_alive() and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(THREAD_START_TIMEOUT_SECONDS)

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._main())
        finally:
            self._loop.close()

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        try:
            await self.simulator.start()
        except BaseException as error:
            self._error = error
            self._started.set()
            return
        self._started.set()
        try:
            await self._stop.wait()
        finally:
            await self.simulator.stop()


async def _as_coroutine(function: Callable[[], Any]) -> Any:
    return function()
