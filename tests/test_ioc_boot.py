"""An IOC whose PLC is not there at start: it keeps running, serves every PV
of the configured or cached chain INVALID/COMM at once, and serves live
values within 5 s of the PLC (the simulator) appearing on its port.

Each IOC keeps its cache in the test's own folder (`XDG_CACHE_HOME`), and
PV names come from `ioc --list-pvs` of the chain file, by source, never
from a naming pattern.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    START_TIMEOUT,
    IocProcess,
    caget,
    free_port,
    ioc_env,
    new_token,
    read_pvs_by_source,
    start_ioc,
    wait_for,
)

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
SINE = "Term 5 (EL3104).AI Compact Channel 1"  # moves all the time
LIVE_WITHIN_S = 5.0
"""Issue 11: live values within 5 s of the PLC appearing."""


def write_config(folder: Path, prefix: str, port: int, **settings: object) -> Path:
    config = folder / "ioc.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "prefix": prefix,
                "target": f"127.0.0.1:{port}",
                "ams_net_id": "127.0.0.1.1.1",
                **settings,
            }
        )
    )
    return config


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


def live_after_the_plc_appears(
    ioc: IocProcess, port: int, env: dict[str, str], pv: str
) -> float:
    """Start the simulator on `port`; seconds until `pv` moves without alarm."""
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR, port=port, env=env):
        appeared = time.monotonic()
        assert wait_for(lambda: moving_without_alarm(ioc, pv), 30), alarm_of(ioc, pv)
        return time.monotonic() - appeared


def test_an_ioc_started_without_its_plc_serves_the_configured_chain(
    tmp_path: Path,
) -> None:
    token = new_token()
    env = {**ioc_env(token), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    prefix = f"BOOT{token[:6].upper()}"
    port = free_port(tcp=True, udp=False)
    config = write_config(tmp_path, prefix, port, chain=str(DEMO_CHAIN))
    sine = read_pvs_by_source(config, env, DEMO_CHAIN)[SINE]

    ioc = serve(config, prefix, env, token)
    try:
        invalid = wait_for(lambda: "COMM INVALID" in alarm_of(ioc, sine), 10)
        connected = caget(ioc, ioc.pv("Connected")).get(ioc.pv("Connected"))
        time.sleep(2)  # retrying: still alive
        alive = ioc.process.poll() is None
        seconds = live_after_the_plc_appears(ioc, port, env, sine)
        still_alive = ioc.process.poll() is None
    finally:
        ioc.stop()

    log = "".join(ioc.output)
    print(f"\nlive values {seconds:.1f} s after the simulator appeared")
    assert invalid and connected == "False", log[-3000:]
    assert alive and still_alive, log[-3000:]
    assert "serving 24 terminals from the chain file" in log
    assert seconds < LIVE_WITHIN_S, log[-3000:]
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
        seconds = live_after_the_plc_appears(second, port, env, sine)
    finally:
        second.stop()

    log = "".join(second.output)
    print(f"\nlive values {seconds:.1f} s after the simulator appeared")
    assert invalid, log[-3000:]
    assert "from the chain kept from the last start" in log, log[-3000:]
    assert seconds < LIVE_WITHIN_S, log[-3000:]
    assert "Traceback" not in log
