"""The image's probes (deploy/image/liveness.sh, stop.sh) run on the host
with the variables the image sets: liveness follows the IOC process, not
the PLC, from the moment it starts waiting for a PLC that is away; stop.sh
stops that waiting IOC; a heartbeat older than the limit is a hung IOC.

tests/test_container.py runs the same scripts inside the built image."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from fastcs_ethercat.runtime import HEARTBEAT_ENV, RUNTIME_ENV
from tests.conftest import REPO_ROOT
from tests.ioc_support import (
    IOC_COMMAND,
    IocProcess,
    free_port,
    ioc_env,
    new_token,
    start_ioc,
    wait_for,
    write_ioc_config,
)

LIVENESS = REPO_ROOT / "deploy" / "image" / "liveness.sh"
STOP = REPO_ROOT / "deploy" / "image" / "stop.sh"
MAX_AGE_ENV = "FASTCS_ETHERCAT_LIVENESS_MAX_AGE_S"
DEFAULT_MAX_AGE_S = 15
WAITING = "nothing to serve until it answers"

pytestmark = pytest.mark.e2e  # every test runs the scripts


@dataclass
class Probe:
    code: int
    said: str


def probe(script: Path, env: dict[str, str]) -> Probe:
    done = subprocess.run(
        ["/bin/bash", str(script)], env=env, capture_output=True, text=True, timeout=30
    )
    return Probe(done.returncode, done.stdout + done.stderr)


def stamp_of(heartbeat: Path) -> tuple[int, float]:
    """(PID, time) of the heartbeat file."""
    pid, _count, stamp = heartbeat.read_text().split()
    return int(pid), float(stamp)


@dataclass
class WaitingIoc:
    ioc: IocProcess
    heartbeat: Path
    env: dict[str, str]


@pytest.fixture
def waiting_ioc(tmp_path: Path) -> Iterator[WaitingIoc]:
    """An IOC as the image runs it (runtime folder, heartbeat file) whose
    target does not answer, with no `chain:` and no chain kept: it waits."""
    token = new_token()
    heartbeat = tmp_path / "heartbeat"
    env = {
        **ioc_env(token),
        RUNTIME_ENV: str(tmp_path / "runtime"),
        HEARTBEAT_ENV: str(heartbeat),
        "XDG_CACHE_HOME": str(tmp_path / "cache"),
    }
    port = free_port(tcp=True, udp=False)
    prefix = f"PROBE{token[:6].upper()}"
    config = write_ioc_config(tmp_path, prefix, f"127.0.0.1:{port}", "127.0.0.1.1.1")
    ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
    try:
        ioc.wait_for_line(WAITING, 90)
        yield WaitingIoc(ioc, heartbeat, env)
    finally:
        ioc.stop()


def test_liveness_passes_while_the_ioc_waits_for_its_plc_and_fails_once_killed(
    waiting_ioc: WaitingIoc,
) -> None:
    ioc, heartbeat, env = waiting_ioc.ioc, waiting_ioc.heartbeat, waiting_ioc.env
    pid, first = stamp_of(heartbeat)
    moved = wait_for(lambda: stamp_of(heartbeat)[1] > first, 5)
    alive = probe(LIVENESS, env)
    time.sleep(5)  # past a short limit: the file must keep moving
    later = probe(LIVENESS, {**env, MAX_AGE_ENV: "2"})
    still_waiting = ioc.child.returncode is None and not any(
        "ioc ready" in line for line in ioc.unread() + ioc.output
    )
    os.kill(ioc.child.pid, signal.SIGKILL)
    ioc.child.wait(10)
    killed = probe(LIVENESS, env)

    assert pid == ioc.child.pid
    assert abs(time.time() - stamp_of(heartbeat)[1]) < 60  # this run's
    assert moved, "the heartbeat file stood still while the IOC waited"
    assert alive.code == 0 and later.code == 0, alive.said + later.said
    assert still_waiting  # the PLC never came: all of it was the wait
    assert killed.code == 1 and "is gone" in killed.said, killed.said


def test_stop_script_stops_the_ioc_waiting_for_its_plc(
    waiting_ioc: WaitingIoc,
) -> None:
    ioc, env = waiting_ioc.ioc, waiting_ioc.env

    stopped = probe(STOP, env)
    code = ioc.child.wait(10)
    after = probe(LIVENESS, env)

    assert stopped.code == 0 and "the IOC exited" in stopped.said, stopped.said
    assert code == 0
    assert after.code == 1, after.said


@pytest.fixture
def sleeper() -> Iterator[int]:
    """A live process the heartbeat file can name (it is not the IOC: the
    script reads only the PID's state and the file's time)."""
    process = subprocess.Popen(["sleep", "300"])
    try:
        yield process.pid
    finally:
        process.kill()
        process.wait(10)


def write_heartbeat(path: Path, pid: int, age_s: float) -> dict[str, str]:
    """A heartbeat file `age_s` old naming `pid`; the probes' environment."""
    path.write_text(f"{pid} 7 {time.time() - age_s:.3f}\n")
    env = {k: v for k, v in os.environ.items() if k != MAX_AGE_ENV}
    return {**env, HEARTBEAT_ENV: str(path)}


def test_a_heartbeat_older_than_the_limit_is_a_hung_ioc(tmp_path: Path) -> None:
    """The hung loop: its process lives (here, this one), its heartbeat
    stopped. The limit is a variable, so no test waits the real 15 s."""
    path, sleeper = tmp_path / "heartbeat", os.getpid()
    fresh = probe(LIVENESS, write_heartbeat(path, sleeper, 1))
    env = write_heartbeat(path, sleeper, DEFAULT_MAX_AGE_S + 5)
    stale = probe(LIVENESS, env)
    stale_within_a_longer_limit = probe(LIVENESS, {**env, MAX_AGE_ENV: "60"})
    env = write_heartbeat(path, sleeper, 3)
    stale_with_a_short_limit = probe(LIVENESS, {**env, MAX_AGE_ENV: "1"})

    assert fresh.code == 0, fresh.said
    assert stale.code == 1 and "hung" in stale.said, stale.said
    assert stale_within_a_longer_limit.code == 0, stale_within_a_longer_limit.said
    assert stale_with_a_short_limit.code == 1, stale_with_a_short_limit.said


def test_a_stopped_or_missing_ioc_fails_liveness(tmp_path: Path, sleeper: int) -> None:
    path = tmp_path / "heartbeat"
    env = write_heartbeat(path, sleeper, 0)
    os.kill(sleeper, signal.SIGSTOP)
    stopped = probe(LIVENESS, env)
    os.kill(sleeper, signal.SIGCONT)
    missing = probe(LIVENESS, {**env, HEARTBEAT_ENV: str(tmp_path / "none")})

    assert stopped.code == 1 and "is stopped" in stopped.said, stopped.said
    assert missing.code == 1 and "no heartbeat file" in missing.said, missing.said
