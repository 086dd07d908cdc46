"""`fastcs-ethercat chain dump` as a user runs it: the simulator's demo chain
read back into a chain file that plays the same rack."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from fastcs_ethercat.chain.file import load_chain
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals.loader import load_terminals
from tests.chain_support import played
from tests.conftest import REPO_ROOT, TERMINALS_DIR, loopback_env
from tests.ioc_support import free_port
from tests.processes import run_cli_child

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"


def dump(*args: str) -> subprocess.CompletedProcess[str]:
    return run_cli_child("chain", "dump", *args, env=loopback_env())


def test_the_demo_chain_dumps_to_a_chain_that_plays_the_same_rack(
    tmp_path: Path,
) -> None:
    out = tmp_path / "rack.yaml"
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR) as sim:
        done = dump("--target", sim.pyads_ip, "--ams-net-id", sim.net_id,
                    "--out", str(out))  # fmt: skip

    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"wrote {out}: 1 master(s), 24 terminals")
    registry = load_terminals([TERMINALS_DIR])
    assert played(load_chain(out), registry) == played(load_chain(DEMO_CHAIN), registry)
    with SimProcess(out, terminals=TERMINALS_DIR) as replay:  # sim --chain FILE
        assert replay.net_id == "127.0.0.1.1.1"


def test_a_target_that_does_not_answer_is_one_line(tmp_path: Path) -> None:
    port = free_port(tcp=True, udp=False)
    done = dump("--target", f"127.0.0.1:{port}", "--ams-net-id", "127.0.0.1.1.1",
                "--out", str(tmp_path / "x.yaml"))  # fmt: skip

    assert done.returncode == 2
    [line] = done.stderr.strip().splitlines()[-1:]
    assert line.startswith("error: target: cannot discover the target:")
    assert "connection refused" in line
    assert not (tmp_path / "x.yaml").exists()


def test_without_a_target_it_says_what_to_give() -> None:
    done = dump("--out", "x.yaml")

    assert done.returncode == 2
    assert done.stderr.strip() == (
        "error: give the target with --target HOST[:PORT] (or --config FILE)"
    )
