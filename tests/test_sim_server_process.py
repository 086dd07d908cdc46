"""`fastcs-ethercat sim` as a process: ready line, control API, clean stop."""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from fastcs_ethercat.process import ChildProcess, parse_ready_line
from fastcs_ethercat.sim.process import SimProcess, SimProcessError
from tests.conftest import REPO_ROOT
from tests.processes import CLI, run_cli_child, running, wait_for_line

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"


@pytest.fixture(scope="module")
def sim() -> Iterator[SimProcess]:
    with SimProcess(DEMO_CHAIN) as sim:
        yield sim


def test_ready_line_names_net_id_and_ports(sim: SimProcess) -> None:
    assert sim.net_id.count(".") == 5
    assert sim.host == "127.0.0.1"
    assert sim.tcp_port > 0 and sim.udp_port > 0
    assert sim.control_url.startswith("http://127.0.0.1:")
    status = sim.status()
    assert status["net_id"] == sim.net_id
    assert status["tcp_port"] == sim.tcp_port


def test_control_api_over_http(sim: SimProcess) -> None:
    before = sim.reset_counters()
    assert before["total"] == 0
    assert sim.add_fault("stall", seconds=0.1)["applied"] == {
        "kind": "stall",
        "seconds": 0.1,
    }
    assert sim.clear_faults() == {"active": []}
    with pytest.raises(SimProcessError, match="404"):
        sim.get_symbol("No such symbol")
    value = "Term 22 (EL3104).AI Standard Channel 1.Value"
    assert sim.set_symbol(value, 4321) == 4321
    channel = sim.get_symbol("Term 22 (EL3104).AI Standard Channel 1")
    assert channel["Value"] == 4321
    assert set(channel["Status"]) >= {"Underrange", "Overrange", "Error"}
    with pytest.raises(SimProcessError, match="400"):
        sim.set_symbol(value, "not a number")
    assert sim.counters()["total"] == 0  # the control API is not ADS


def test_sigint_and_sigterm_stop_cleanly() -> None:
    for signum in (signal.SIGINT, signal.SIGTERM):
        process = SimProcess(DEMO_CHAIN)
        process.start()
        assert process.returncode is None
        os.kill(process.pid, signum)
        assert process.wait(10) == 0
        process.stop()


def test_cli_prints_the_ready_line_with_default_host() -> None:
    args = [*CLI, "sim", "--chain", str(DEMO_CHAIN), "--port", "0", "--udp-port", "0"]
    child = ChildProcess(args, "sim")
    try:
        fields = child.start(60)
        assert parse_ready_line(child.lines[0], "sim") == fields  # its first line
        assert fields["tcp"].startswith("127.0.0.1:")
        assert fields["udp"].startswith("127.0.0.1:")
        assert fields["control"] == "off"
    finally:
        assert child.stop() == 0  # SIGTERM: a clean exit
        child.close()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--chain", "no-such-chain.yaml"], "no-such-chain.yaml"),
        (["--chain", str(DEMO_CHAIN), "--port", "70000"], "--port"),
        (["--chain", str(DEMO_CHAIN), "--terminals", "no-such-dir"], "no-such-dir"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(
    args: list[str], message: str, tmp_path: Path
) -> None:
    done = run_cli_child("sim", *args, timeout=60)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("error: ")
    assert message in line


def test_busy_port_is_a_user_error() -> None:
    with SimProcess(DEMO_CHAIN) as first:
        done = run_cli_child("sim", "--chain", DEMO_CHAIN, "--port",
                             str(first.tcp_port), "--udp-port", "0",
                             timeout=60)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.startswith("error: cannot listen")
    assert "Traceback" not in done.stderr


def test_a_bad_chain_file_is_one_line(tmp_path: Path) -> None:
    chain = tmp_path / "bad.yaml"
    chain.write_text("masters: [}\n")
    done = run_cli_child("sim", "--chain", chain, "--port", "0", "--udp-port", "0",
                         timeout=60)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1
    assert "bad.yaml" in done.stderr


def test_sim_process_reports_a_simulator_that_never_gets_ready(tmp_path: Path) -> None:
    with pytest.raises(SimProcessError, match="did not get ready"):
        SimProcess(tmp_path / "missing.yaml", ready_timeout=30).start()


PARENT_SCRIPT = """
import sys, time
from fastcs_ethercat.sim.process import SimProcess
sim = SimProcess(sys.argv[1])
sim.start()
print(sim.pid, flush=True)
time.sleep(60)
"""


def test_the_simulator_follows_a_parent_that_dies_without_cleaning_up() -> None:
    parent = ChildProcess(
        [sys.executable, "-c", PARENT_SCRIPT, str(DEMO_CHAIN)], "parent"
    )
    with parent:
        parent.launch()
        sim_pid = int(wait_for_line(parent, r"^\d+$", 60))
        assert running(sim_pid)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(10)
    deadline = time.monotonic() + 10
    while running(sim_pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not running(sim_pid)
