"""SIGTERM and SIGHUP stop every command cleanly, exit 0 and no traceback,
at any moment of its life (`fastcs_ethercat.stop_signals`): while reading
its input, while the IOC waits for the PLC at boot, while it serves, and
`demo` takes its simulator child with it when its terminal closes."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from fastcs_ethercat.process import ChildProcess, free_port
from tests.conftest import loopback_env
from tests.processes import CLI, running, wait_for_line

pytestmark = pytest.mark.e2e

STOPS = [signal.SIGTERM, signal.SIGHUP]
WAIT_S = 60.0


@contextmanager
def command(*args: str, env: dict[str, str] | None = None) -> Iterator[ChildProcess]:
    """`fastcs-ethercat ARGS` running, its stdout and stderr read as they
    come; stopped by PID at the end, whatever the test did."""
    child = ChildProcess(
        [*CLI, *args], "command", env=env or loopback_env(), merge_stderr=True
    )
    child.launch()
    try:
        yield child
    finally:
        child.close()


def wait_for(child: ChildProcess, text: str) -> None:
    wait_for_line(child, re.escape(text), WAIT_S)


def stop_with(child: ChildProcess, signum: int) -> int:
    """Send `signum` by PID; the exit code, once every line is read."""
    os.kill(child.pid, signum)
    try:
        return child.wait(WAIT_S)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"still running after {signum!r}") from None


def assert_clean(child: ChildProcess, code: int) -> None:
    text = "\n".join(child.lines)
    assert code == 0, text[-2000:]
    assert "Traceback" not in text and "CancelledError" not in text, text


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_the_ioc_waiting_for_the_plc_at_boot_stops_cleanly(
    tmp_path: Path, signum: signal.Signals
) -> None:
    config = tmp_path / "ioc.yaml"
    config.write_text(
        f"prefix: SIGT\ntarget: 127.0.0.1:{free_port(tcp=True, udp=False)}\n"
        "ams_net_id: 127.0.0.1.1.1\n"
    )
    env = loopback_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    with command("ioc", "--config", str(config), env=env) as ioc:
        wait_for(ioc, "nothing to serve until it answers")
        assert_clean(ioc, stop_with(ioc, signum))


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
            code = stop_with(blocked, signum)
        assert_clean(blocked, code)


def _children(pid: int) -> list[int]:
    found = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True)
    return [int(text) for text in found.stdout.split()]


def _gone(pid: int, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not running(pid):
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_demo_stops_and_takes_its_simulator_along(
    tmp_path: Path, signum: signal.Signals
) -> None:
    env = loopback_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    with command("demo", "--prefix", "SIGD", env=env) as demo:
        wait_for(demo, "demo: Ctrl-C to stop")
        children = _children(demo.pid)
        assert children, "the demo runs its simulator as a child"
        assert_clean(demo, stop_with(demo, signum))
    assert all(_gone(child) for child in children)


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_the_simulator_stops_cleanly(signum: signal.Signals) -> None:
    from tests.conftest import REPO_ROOT

    chain = str(REPO_ROOT / "ioc" / "demo-chain.yaml")
    args = ["sim", "--chain", chain, "--port", "0", "--udp-port", "0"]
    with command(*args, "--control-port", "0") as sim:
        wait_for(sim, "ready")
        assert_clean(sim, stop_with(sim, signum))


@pytest.mark.parametrize("signum", STOPS, ids=lambda s: s.name)
def test_the_editor_stops_cleanly(tmp_path: Path, signum: signal.Signals) -> None:
    pytest.importorskip("nicegui")
    folder = tmp_path / "terminals"
    folder.mkdir()
    env = loopback_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    env.pop("PYTEST_CURRENT_TEST", None)  # NiceGUI would take it for its own tests
    args = ["terminals", "edit", str(folder), "--port", "0"]
    with command(*args, env=env) as editor:
        wait_for(editor, "terminals edit ready")
        assert_clean(editor, stop_with(editor, signum))
