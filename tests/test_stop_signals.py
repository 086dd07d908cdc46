"""SIGTERM and SIGHUP stop every command cleanly, exit 0 and no traceback,
at any moment of its life (`fastcs_ethercat.stop_signals`): while reading
its input, while the IOC waits for the PLC at boot, while it serves, and
`demo` takes its simulator child with it when its terminal closes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.conftest import loopback_env

pytestmark = pytest.mark.e2e

STOPS = [signal.SIGTERM, signal.SIGHUP]
WAIT_S = 60.0


class Command:
    """`fastcs-ethercat ARGS` with its stderr read as it comes."""

    def __init__(self, *args: str, env: dict[str, str] | None = None) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "fastcs_ethercat", *args],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env or loopback_env(),
        )
        self.err: list[str] = []
        self.out: list[str] = []
        self._readers = [
            threading.Thread(target=self._read, args=(stream, lines), daemon=True)
            for stream, lines in (
                (self.process.stderr, self.err),
                (self.process.stdout, self.out),
            )
        ]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(stream: object, lines: list[str]) -> None:
        for line in stream:  # type: ignore[attr-defined]
            lines.append(line)

    def wait_for(self, text: str, timeout: float = WAIT_S) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(text in line for line in self.err + self.out):
                return
            if self.process.poll() is not None:
                break
            time.sleep(0.05)
        self.stop_hard()
        raise AssertionError(f"never saw {text!r}:\n{''.join(self.err)[-2000:]}")

    def stop_with(self, signum: int) -> int:
        self.process.send_signal(signum)
        try:
            code = self.process.wait(WAIT_S)
        except subprocess.TimeoutExpired:
            self.stop_hard()
            raise AssertionError(f"still running after {signum!r}") from None
        for reader in self._readers:
            reader.join(5)
        return code

    def stop_hard(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)

    def assert_clean(self, code: int) -> None:
        text = "".join(self.err)
        assert code == 0, text[-2000:]
        assert "Traceback" not in text and "CancelledError" not in text, text


@contextmanager
def command(*args: str, env: dict[str, str] | None = None) -> Iterator[Command]:
    running = Command(*args, env=env)
    try:
        yield running
    finally:
        running.stop_hard()


def _free_port() -> int:
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_the_ioc_waiting_for_the_plc_at_boot_stops_cleanly(
    tmp_path: Path, signum: signal.Signals
) -> None:
    config = tmp_path / "ioc.yaml"
    config.write_text(
        f"prefix: SIGT\ntarget: 127.0.0.1:{_free_port()}\nams_net_id: 127.0.0.1.1.1\n"
    )
    env = loopback_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    with command("ioc", "--config", str(config), env=env) as ioc:
        ioc.wait_for("nothing to serve until it answers")
        ioc.assert_clean(ioc.stop_with(signum))


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_a_command_blocked_reading_its_input_stops_cleanly(
    tmp_path: Path, signum: signal.Signals
) -> None:
    fifo = tmp_path / "ioc.yaml"
    os.mkfifo(fifo)
    with command("ioc", "--config", str(fifo), "--list-pvs") as blocked:
        with fifo.open("w") as writer:  # returns once the command opened it
            writer.write("prefix: X\n")
            writer.flush()
            time.sleep(0.2)  # it now waits in read() for the rest
            code = blocked.stop_with(signum)
        blocked.assert_clean(code)


def _children(pid: int) -> list[int]:
    found = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True)
    return [int(text) for text in found.stdout.split()]


def _gone(pid: int, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not Path(f"/proc/{pid}").exists():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_demo_stops_and_takes_its_simulator_along(
    tmp_path: Path, signum: signal.Signals
) -> None:
    env = loopback_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    with command("demo", "--prefix", "SIGD", env=env) as demo:
        demo.wait_for("demo: Ctrl-C to stop")
        children = _children(demo.process.pid)
        assert children, "the demo runs its simulator as a child"
        demo.assert_clean(demo.stop_with(signum))
    assert all(_gone(child) for child in children)


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_the_simulator_stops_cleanly(signum: signal.Signals) -> None:
    from tests.conftest import REPO_ROOT

    chain = str(REPO_ROOT / "ioc" / "demo-chain.yaml")
    args = ["sim", "--chain", chain, "--port", "0", "--udp-port", "0"]
    with command(*args, "--control-port", "0") as sim:
        sim.wait_for("ready")
        sim.assert_clean(sim.stop_with(signum))


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_the_editor_stops_cleanly(tmp_path: Path, signum: signal.Signals) -> None:
    pytest.importorskip("nicegui")
    folder = tmp_path / "terminals"
    folder.mkdir()
    env = loopback_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    env.pop("PYTEST_CURRENT_TEST", None)  # NiceGUI would take it for its own tests
    args = ["terminals", "edit", str(folder), "--port", "0"]
    with command(*args, env=env) as editor:
        editor.wait_for("terminals edit ready")
        editor.assert_clean(editor.stop_with(signum))
