"""The image as a beamline runs it.

Built with `deploy/build-image.sh` (on a machine that never built it, the
base image is made with debootstrap first), then run with podman and host
networking: the IOC in the container against a simulator on the host, with
its instance config mounted at /epics/ioc/config, read with the host's
`caget` and `pvget`, stopped with SIGTERM. `demo` runs inside the image too.
Prints the build time, the image size and the containerised IOC's memory
and CPU. Skips in one line where podman, runc or debootstrap is missing
(`.ci/run` installs them).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT
from tests.ioc_support import IocProcess, caget, ioc_env, start_ioc, wait_for
from tests.processes import new_token, processes_with_token, stop_pid

pytestmark = [pytest.mark.e2e, pytest.mark.perf, pytest.mark.slow]

IMAGE = "localhost/fastcs-ethercat:test"
PODMAN = str(REPO_ROOT / "deploy" / "podman.sh")
BUILD_TIMEOUT_S = 1500
DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
PV = "ETH1:RIO1:MOD5:CH1:Value"
STOP_LIMIT_S = 2.0

_MISSING = [
    tool for tool in ("podman", "runc", "debootstrap") if not shutil.which(tool)
]
if _MISSING:
    pytest.skip(
        f"no {', '.join(_MISSING)}: apt-get install podman runc debootstrap "
        "(.ci/run does)",
        allow_module_level=True,
    )


def _podman(*args: str, timeout: float = 120) -> str:
    done = subprocess.run(
        [PODMAN, *args], capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, f"podman {' '.join(args)}: {done.stderr[-2000:]}"
    return done.stdout


@pytest.fixture(scope="module")
def image() -> Iterator[str]:
    """The image, built now; removed afterwards (vfs keeps a full copy of
    each image, and the next run builds again: only the base is kept)."""
    started = time.monotonic()
    done = subprocess.run(
        [str(REPO_ROOT / "deploy" / "build-image.sh"), IMAGE],
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT_S,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    size = int(_podman("image", "inspect", "--format", "{{.Size}}", IMAGE))
    print(
        f"\nimage {IMAGE}: built in {time.monotonic() - started:.0f} s, "
        f"{size / 1e6:.0f} MB"
    )
    yield IMAGE
    subprocess.run([PODMAN, "rmi", "--force", IMAGE], capture_output=True)


def _env_flags(env: dict[str, str]) -> list[str]:
    """The EPICS variables of `env` as podman --env flags (loopback, ports)."""
    return [
        flag
        for key, value in env.items()
        if key.startswith("EPICS_")
        for flag in ("--env", f"{key}={value}")
    ]


def _run(
    name: str, prefix: str, env: dict[str, str], token: str, *args: str
) -> IocProcess:
    """`podman run` of the image (attached, so its output is the IOC's)."""
    command = [PODMAN, "run", "--rm", "--name", name, "--network", "host"]
    return start_ioc([*command, *_env_flags(env), *args], prefix, env, token)


@pytest.fixture
def token() -> Iterator[str]:
    token = new_token()
    yield token
    for pid in processes_with_token(token):  # host caget's caRepeater
        stop_pid(pid)


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _alive(pid: int) -> bool:
    """The process runs (an exited one waiting to be reaped does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] not in ("Z", "X")


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def test_ioc_in_the_image_serves_the_host_and_stops_on_sigterm(
    image: str, tmp_path: Path, token: str
) -> None:
    env = ioc_env(token)
    prefix = f"CTR{token[:6].upper()}"
    name = f"fastcs-ethercat-test-{token}"
    config_dir, screens = tmp_path / "config", tmp_path / "opi"
    config_dir.mkdir()
    screens.mkdir(mode=0o777)
    screens.chmod(0o777)  # the image's user (uid 1000) writes the screens
    with SimProcess(chain=DEMO_CHAIN, env=env) as sim:
        (config_dir / "ioc.yaml").write_text(
            yaml.safe_dump(
                {
                    "prefix": prefix,
                    "target": sim.pyads_ip,
                    "ams_net_id": sim.net_id,
                    "screens_dir": "/epics/opi",
                }
            )
        )
        ioc = _run(
            name,
            prefix,
            env,
            token,
            "--volume",
            f"{config_dir}:/epics/ioc/config:ro",
            "--volume",
            f"{screens}:/epics/opi",
            image,
        )
        try:
            ioc.wait_for_line("ioc ready", 120)
            pv = ioc.pv(PV)
            first = wait_for(lambda: caget(ioc, pv).get(pv), 30)
            moved = wait_for(lambda: caget(ioc, pv).get(pv) not in (None, first), 10)
            pva = ioc.tool("pvget", pv)
            pid = int(_podman("inspect", "--format", "{{.State.Pid}}", name))
            cpu_start, clock = _cpu_seconds(pid), time.monotonic()
            time.sleep(5)
            cpu = (_cpu_seconds(pid) - cpu_start) / (time.monotonic() - clock)
            print(
                f"\ncontainer IOC (24 terminals, 10 Hz): RSS {_rss_mb(pid):.0f} MB, "
                f"CPU {100 * cpu:.0f} % of a core"
            )
            _podman("kill", "--signal", "TERM", name)
            stopping = time.monotonic()
            wait_for(lambda: not _alive(pid), 30)
            stopped_in = time.monotonic() - stopping
            print(f"SIGTERM to exit of the IOC: {stopped_in:.2f} s")
            ioc.process.wait(60)  # podman then removes the container
        finally:
            subprocess.run([PODMAN, "rm", "--force", name], capture_output=True)
            ioc.stop()

    assert first is not None and moved
    assert pv in pva
    assert stopped_in < STOP_LIMIT_S
    assert (screens / "index.bob").is_file()
    assert f"{prefix}:ETH1:RIO1:MOD5:AlState" in (screens / "ETH1.bob").read_text()


def test_demo_runs_inside_the_image(image: str, token: str) -> None:
    env = ioc_env(token)
    prefix = f"DMO{token[:6].upper()}"
    name = f"fastcs-ethercat-demo-{token}"
    demo = _run(name, prefix, env, token, image, "demo", "--prefix", prefix)
    try:
        demo.wait_for_line(r"^demo: try ", 120)
        pv = demo.pv(PV)
        value = wait_for(lambda: caget(demo, pv).get(pv), 30)
    finally:
        subprocess.run([PODMAN, "rm", "--force", name], capture_output=True)
        demo.stop()

    assert value is not None and abs(float(value)) <= 10.001  # volts (EL3104, +/-10 V)
