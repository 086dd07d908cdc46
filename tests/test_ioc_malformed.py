"""An IOC whose target turns hostile: it survives every malformed frame,
keeps its log short, and serves again when the target is good again; and it
never loads AdsLib's native code.

The IOC (a subprocess) starts against the simulator through a proxy in this
process; the proxy then answers every request with bursts of malformed
frames (`tests.malformed_ads`) until over a thousand went out, then forwards
again. The same at start: an IOC started while the proxy is hostile (no
chain to serve meanwhile) keeps trying, and serves once the proxy is good.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    START_TIMEOUT,
    IocProcess,
    caget,
    ioc_env,
    new_token,
    read_pvs_by_source,
    start_ioc,
    wait_for,
    write_ioc_config,
)
from tests.malformed_ads import HostileProxy, ProxyThread

pytestmark = pytest.mark.e2e

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
SINE = "ETH1:RIO1:MOD5:CH1:Value"  # moves all the time
SINE_SYMBOL = "Term 5 (EL3104).AI Compact Channel 1"
MALFORMED_FRAMES = 1000
LOG_LINES_PER_MINUTE = 100


def drain(ioc: IocProcess) -> list[str]:
    """The IOC's output lines that came since the last drain."""
    return ioc.unread()


def root(ioc: IocProcess, name: str) -> str:
    pv = ioc.pv(name)
    return caget(ioc, "-S", pv).get(pv, "")


def moves(ioc: IocProcess, pv: str) -> bool:
    first = caget(ioc, pv).get(pv)
    time.sleep(0.3)
    return first is not None and caget(ioc, pv).get(pv) != first


def sine_moves(ioc: IocProcess) -> bool:
    return moves(ioc, ioc.pv(SINE))


def enough_sent_or_dead(proxy: HostileProxy, ioc: IocProcess) -> bool:
    """Wait until MALFORMED_FRAMES went out (or the IOC died): whether they did."""
    return wait_for(
        lambda: (
            proxy.malformed_sent >= MALFORMED_FRAMES or ioc.child.returncode is not None
        ),
        180,
    )


def test_the_ioc_survives_a_hostile_target(tmp_path: Path) -> None:
    token = new_token()
    env = ioc_env(token)
    prefix = f"HOSTILE{token[:6].upper()}"
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR, env=env) as sim:
        hostile = HostileProxy(("127.0.0.1", sim.tcp_port), burst=100)
        with ProxyThread(hostile) as proxy:
            config = write_ioc_config(
                tmp_path,
                prefix,
                f"127.0.0.1:{proxy.port}",
                sim.net_id,
                ads_timeout_ms=500,
            )
            ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
            try:
                ioc.wait_for_line("ioc ready", START_TIMEOUT)
                maps = Path(f"/proc/{ioc.child.pid}/maps").read_text()
                assert wait_for(lambda: root(ioc, "Connected") == "True", 30)
                assert sine_moves(ioc)
                drain(ioc)

                started = time.monotonic()
                proxy.bad = True
                lost = wait_for(lambda: root(ioc, "Connected") == "False", 20)
                sent = enough_sent_or_dead(proxy, ioc)
                alive_while_bad = ioc.child.returncode is None
                proxy.bad = False
                bad_seconds = time.monotonic() - started
                bad_lines = drain(ioc)

                back = wait_for(
                    lambda: (
                        root(ioc, "ConnectionState") == "CONNECTED"
                        and root(ioc, "InvalidPvs") == "0"
                    ),
                    60,
                )
                moving = back and sine_moves(ioc)
                alive = ioc.child.returncode is None
            finally:
                ioc.stop()

    assert "adslib" not in maps.lower(), "the IOC loaded AdsLib's native code"
    assert sent and proxy.malformed_sent >= MALFORMED_FRAMES, dict(proxy.sent)
    assert alive_while_bad and alive, "".join(ioc.output[-40:])
    assert lost
    assert back and moving
    per_minute = len(bad_lines) * 60 / bad_seconds
    print(
        f"\n{proxy.malformed_sent} malformed frames in {bad_seconds:.0f} s, "
        f"{len(bad_lines)} log lines ({per_minute:.0f} a minute), "
        f"{proxy.connections} connections"
    )
    assert per_minute < LOG_LINES_PER_MINUTE, "".join(bad_lines[-40:])


def test_an_ioc_started_against_a_hostile_target_serves_once_it_turns_good(
    tmp_path: Path,
) -> None:
    token = new_token()
    env = {**ioc_env(token), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    prefix = f"HOSTART{token[:6].upper()}"
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR, env=env) as sim:
        hostile = HostileProxy(("127.0.0.1", sim.tcp_port), burst=250)
        hostile.bad = True
        with ProxyThread(hostile) as proxy:
            config = write_ioc_config(
                tmp_path,
                prefix,
                f"127.0.0.1:{proxy.port}",
                sim.net_id,
                ads_timeout_ms=500,
            )
            sine = read_pvs_by_source(config, env, DEMO_CHAIN)[SINE_SYMBOL]
            started = time.monotonic()
            ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
            try:
                sent = enough_sent_or_dead(proxy, ioc)
                alive_while_bad = ioc.child.returncode is None
                bad_seconds = time.monotonic() - started
                bad_lines = drain(ioc)
                proxy.bad = False
                ioc.wait_for_line("ioc ready", START_TIMEOUT)
                moving = wait_for(lambda: moves(ioc, sine), 30)
                alive = ioc.child.returncode is None
            finally:
                ioc.stop()
            rest = drain(ioc)

    assert sent and proxy.malformed_sent >= MALFORMED_FRAMES, dict(proxy.sent)
    assert alive_while_bad and alive, "".join(bad_lines[-40:] + ioc.output[-40:])
    assert moving, "".join(ioc.output[-40:])
    per_minute = len(bad_lines) * 60 / bad_seconds
    print(
        f"\n{proxy.malformed_sent} malformed frames at start in {bad_seconds:.0f} s, "
        f"{len(bad_lines)} log lines ({per_minute:.0f} a minute)"
    )
    assert per_minute < LOG_LINES_PER_MINUTE, "".join(bad_lines[-40:])
    assert not any("Traceback" in line for line in bad_lines + ioc.output + rest)
