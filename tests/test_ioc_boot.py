"""An IOC whose PLC is not there at start: it keeps running, serves every PV
of the configured or cached chain INVALID/COMM at once, and serves live
values within 5 s of the PLC (the simulator) appearing on its port.

Each IOC keeps its cache in the test's own folder (`XDG_CACHE_HOME`), and
PV names come from `ioc --list-pvs` of the chain file, by source, never
from a naming pattern.
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    START_TIMEOUT,
    IocProcess,
    caget,
    free_port,
    ioc_env,
    list_pvs,
    list_pvs_text,
    new_token,
    read_pvs_by_source,
    start_ioc,
    wait_for,
    write_ioc_config,
)

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
SINE = "Term 5 (EL3104).AI Compact Channel 1"  # moves all the time
RAMP = "Term 13 (EL3602).AI Inputs Channel 2.Value"  # moves all the time
STANDARD = "Term 5 (EL3104).AI Standard Channel 1.Value"
LIVE_WITHIN_S = 25.0
"""Live values once the PLC appears, a generous bound of the behaviour: the
target (5 s, issue 11) is `fastcs-ethercat bench --only faults`'s figure."""


def write_config(folder: Path, prefix: str, port: int, **settings: object) -> Path:
    return write_ioc_config(
        folder, prefix, f"127.0.0.1:{port}", "127.0.0.1.1.1", **settings
    )


def everything_said(ioc: IocProcess) -> str:
    """The IOC's whole output, including what no `wait_for_line` read."""
    ioc.unread()
    return "".join(ioc.output)


def alarm_of(ioc: IocProcess, pv: str) -> str:
    """caget -a's last words: `COMM INVALID`, or the value when in no alarm."""
    return ioc.tool("caget", "-a", pv).strip()


def moving_without_alarm(ioc: IocProcess, pv: str) -> bool:
    first = caget(ioc, "-a", pv).get(pv, "")
    time.sleep(0.2)
    second = caget(ioc, "-a", pv).get(pv, "")
    return bool(first) and "INVALID" not in second and first != second


def serve(config: Path, prefix: str, env: dict[str, str], token: str) -> IocProcess:
    ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
    ioc.wait_for_line("ioc ready", START_TIMEOUT)
    return ioc


@contextlib.contextmanager
def plc_appears(
    ioc: IocProcess, port: int, env: dict[str, str], pv: str
) -> Iterator[float]:
    """Start the simulator on `port`; yield the seconds until `pv` moved
    without alarm, while the simulator still runs."""
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR, port=port, env=env):
        appeared = time.monotonic()
        assert wait_for(lambda: moving_without_alarm(ioc, pv), 30), alarm_of(ioc, pv)
        yield time.monotonic() - appeared


def test_an_ioc_started_without_its_plc_serves_the_configured_chain(
    tmp_path: Path,
) -> None:
    """The configured chain says Term 5 runs Standard; the PLC that comes
    runs Compact (the demo chain): one line says what differs."""
    token = new_token()
    env = {**ioc_env(token), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    prefix = f"BOOT{token[:6].upper()}"
    port = free_port(tcp=True, udp=False)
    chain = tmp_path / "rack.yaml"
    chain.write_text(
        DEMO_CHAIN.read_text().replace("pdo_group: Compact", "pdo_group: Standard")
    )
    config = write_config(
        tmp_path, prefix, port, chain=str(chain), pv_lists_dir="lists"
    )
    rows = list_pvs(config, env)  # of the configured chain, without the PLC
    listed = json.loads(list_pvs_text(config, env, "--format", "archiver"))
    names = read_pvs_by_source(config, env, chain)
    ramp, standard = names[RAMP], names[STANDARD]

    ioc = serve(config, prefix, env, token)
    try:
        ioc.wait_for_line("PV lists written", 30)
        archived = json.loads((tmp_path / "lists" / "archiver.json").read_text())
        invalid = wait_for(lambda: "COMM INVALID" in alarm_of(ioc, ramp), 10)
        connected = caget(ioc, ioc.pv("Connected")).get(ioc.pv("Connected"))
        time.sleep(2)  # retrying: still alive
        alive = ioc.child.returncode is None
        with plc_appears(ioc, port, env, ramp) as seconds:
            gone = wait_for(lambda: "STATE INVALID" in alarm_of(ioc, standard), 10)
        still_alive = ioc.child.returncode is None
    finally:
        ioc.stop()

    log = everything_said(ioc)
    print(f"\nlive values {seconds:.1f} s after the simulator appeared")
    assert invalid and connected == "False", log[-3000:]
    assert alive and still_alive, log[-3000:]
    assert f"serving 24 terminals from the chain file {chain}" in log
    assert seconds < LIVE_WITHIN_S, log[-3000:]
    assert gone, log[-3000:]
    assert archived == listed  # written at start from the chain's tree
    assert {item["pv"].removeprefix("pva://") for item in archived} <= {
        r[0] for r in rows if "r" in r[1]
    }
    [differs] = [line for line in log.splitlines() if "chain (the live one" in line]
    assert "served points gone or changed type" in differs
    assert "live points not served until restart" in differs
    assert "Traceback" not in log
    assert (tmp_path / "cache" / "fastcs-ethercat" / "chains").is_dir()  # kept


def test_an_ioc_started_without_its_plc_serves_the_chain_it_saw_last(
    tmp_path: Path,
) -> None:
    token = new_token()
    env = {**ioc_env(token), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    prefix = f"CACHE{token[:6].upper()}"
    port = free_port(tcp=True, udp=False)
    config = write_config(tmp_path, prefix, port)
    sine = read_pvs_by_source(config, env, DEMO_CHAIN)[SINE]

    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR, port=port, env=env):
        first = serve(config, prefix, env, token)
        try:
            assert wait_for(lambda: moving_without_alarm(first, sine), 30)
        finally:
            first.stop()

    second = serve(config, prefix, env, token)  # the PLC is gone now
    try:
        invalid = wait_for(lambda: "COMM INVALID" in alarm_of(second, sine), 10)
        with plc_appears(second, port, env, sine) as seconds:
            pass
    finally:
        second.stop()

    log = everything_said(second)
    print(f"\nlive values {seconds:.1f} s after the simulator appeared")
    assert invalid, log[-3000:]
    assert "from the chain kept from the last start" in log, log[-3000:]
    assert seconds < LIVE_WITHIN_S, log[-3000:]
    assert "Traceback" not in log
