"""A long start an operator can follow: the 104-terminal rack of the
benchmarks with every CoE object selected starts with no traceback, at most
20 lines of warnings, and says how far it got (discovered, planned, serving,
CoE values read)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fastcs_ethercat.bench.chains import (
    demo_mix,
    mixed_slaves,
    terminals_with_coe,
    write_chain,
)
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    ioc_env,
    new_token,
    start_ioc,
    write_ioc_config,
)

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
TERMINALS = 104
WARNING_LINES = 20
"""Issue 15: at most 20 log lines of warnings (errors counted with them)."""
PROGRESS = (
    rf"discovered {TERMINALS} terminals on 1 master\(s\)",
    r"\d+ PVs planned in",
    rf"serving \d+ PVs of {TERMINALS} terminals",
)


def test_104_terminals_with_every_coe_object_start_quietly(tmp_path: Path) -> None:
    chain = write_chain(
        tmp_path / "chain.yaml", mixed_slaves(TERMINALS, demo_mix(DEMO_CHAIN))
    )
    terminals = terminals_with_coe(TERMINALS_DIR, tmp_path / "terminals")
    token = new_token()
    env = {**ioc_env(token), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    prefix = f"BIG{token[:6].upper()}"
    with SimProcess(chain, terminals=terminals, env=env) as sim:
        config = write_ioc_config(
            tmp_path, prefix, sim.pyads_ip, sim.net_id, terminal_dirs=[str(terminals)]
        )
        ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
        try:
            ioc.wait_for_line("ioc ready", 300)
            ioc.wait_for_line(r"CoE values of \d+ terminals read", 600)
        finally:
            ioc.stop()

    log = "".join(ioc.output)
    warnings = [line for line in ioc.output if " WARNING " in line or " ERROR " in line]
    print(f"\n{len(ioc.output)} log lines, {len(warnings)} warnings:\n" + log)
    assert "Traceback" not in log, log[-5000:]
    assert len(warnings) <= WARNING_LINES, log[-5000:]
    for progress in PROGRESS:
        assert re.search(progress, log), progress
