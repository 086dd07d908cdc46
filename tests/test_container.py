"""The image as a beamline runs it.

Built once per session with `deploy/build-image.sh`, from a tagged checkout
of the working tree and with a Python whose pip is older than 24 (the build
brings its own pip; on a machine that never built it, the base image is made
with debootstrap first), then run with podman and host networking: the IOC
in the container against a simulator on the host, with its instance config
mounted at /epics/ioc/config, read with the host's
`caget` and `pvget`, stopped with SIGTERM. `demo` runs inside the image too.
The probes: liveness follows the IOC (not the PLC), preStop stops it; a pod
shaped like the ioc-instance chart's (`podman kube play`) stays healthy.
Prints the build time, the image size and the containerised IOC's memory
and CPU. Skips in one line where podman, runc or debootstrap is missing
(`.ci/run` installs them).
"""

from __future__ import annotations

import getpass
import os
import shutil
import subprocess
import time
import venv
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT
from tests.ioc_support import (
    BIN,
    IocProcess,
    caget,
    ioc_env,
    start_ioc,
    wait_for,
)
from tests.processes import new_token, processes_with_token, stop_pid
from tests.tagged_checkout import tagged_checkout

pytestmark = [pytest.mark.e2e, pytest.mark.perf, pytest.mark.slow]

IMAGE = "localhost/fastcs-ethercat:test"
PODMAN = str(REPO_ROOT / "deploy" / "podman.sh")
BUILD_TIMEOUT_S = 1500
DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
PV = "ETH1:RIO1:MOD5:CH1:Value"
OUTPUT = "ETH1:RIO21:MOD24:CH4:AnalogOutput"
STOP_LIMIT_S = 2.0
RELEASE = "9.8.7"
"""The tag (v9.8.7) of the checkout the image is built from."""
VALUES = REPO_ROOT / "deploy" / "services" / "bl01t-ea-ecat-01" / "values.yaml"
HEALTHY_FOR_S = 300.0
LIVENESS = ["/bin/bash", "/epics/ioc/liveness.sh"]
PRESTOP = ["/bin/bash", "/epics/ioc/stop.sh"]
HEARTBEAT_FILE = "/tmp/fastcs-ethercat.heartbeat"

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


def _old_pip_python(where: Path) -> str:
    """A venv's Python whose pip is older than 24 (Debian 12 has 23.2)."""
    venv.create(where, with_pip=True)
    python = str(where / "bin" / "python")
    subprocess.run(
        [python, "-m", "pip", "install", "-q", "pip<24"],
        check=True,
        capture_output=True,
        timeout=300,
    )
    version = subprocess.run(
        [python, "-m", "pip", "--version"], check=True, capture_output=True, text=True
    ).stdout.split()[1]
    assert int(version.split(".")[0]) < 24, version
    return python


@pytest.fixture(scope="module")
def image(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The image, built now from a checkout tagged v9.8.7 with a Python
    whose pip is older than 24; removed afterwards (vfs keeps a full copy of
    each image, and the next run builds again: only the base is kept)."""
    work = tmp_path_factory.mktemp("image")
    checkout = tagged_checkout(work / "checkout", f"v{RELEASE}")
    python = _old_pip_python(work / "old-pip")
    started = time.monotonic()
    done = subprocess.run(
        [str(checkout / "deploy" / "build-image.sh"), IMAGE],
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT_S,
        env={**os.environ, "PYTHON": python},
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
            # The image's CMD, quieter: podman passes the container's stdout
            # (the put lines) and stderr (the log) on in chunks of its own,
            # so a log line at the put's moment could split the put line.
            *[
                "ioc",
                "--config",
                "/epics/ioc/config/ioc.yaml",
                "--log-level",
                "warning",
            ],
        )
        try:
            ioc.wait_for_line("ioc ready", 120)
            pv = ioc.pv(PV)
            first = wait_for(lambda: caget(ioc, pv).get(pv), 30)
            moved = wait_for(lambda: caget(ioc, pv).get(pv) not in (None, first), 10)
            pva = ioc.tool("pvget", pv)
            uptime, heartbeat = ioc.pv("UPTIME"), ioc.pv("HEARTBEAT")
            beat = caget(ioc, heartbeat).get(heartbeat)
            beat_moved = wait_for(
                lambda: caget(ioc, heartbeat).get(heartbeat) not in (None, beat), 10
            )
            uptime_text = caget(ioc, "-S", uptime).get(uptime)
            ioc.tool("caput", ioc.pv(OUTPUT), "123")
            audit = ioc.wait_for_line(rf"@\S+ {ioc.pv(OUTPUT)}\.VAL \S+ -> 123", 10)
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
            ioc.child.wait(60)  # podman then removes the container
        finally:
            subprocess.run([PODMAN, "rm", "--force", name], capture_output=True)
            ioc.stop()

    assert first is not None and moved
    assert pv in pva
    assert beat is not None and beat_moved
    assert uptime_text and " days, " in uptime_text
    assert audit.split("@")[0].strip() == getpass.getuser()  # caput's user
    widgets = [w for bob in screens.glob("*.bob")
               for w in ElementTree.parse(bob).iter("widget")]  # fmt: skip
    strings = [w for w in widgets if (w.findtext("pv_name") or "").endswith(":Type")]
    assert strings and all(w.findtext("format") == "6" for w in strings)
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


def test_version_is_the_tag_of_the_checkout(image: str) -> None:
    printed = _podman("run", "--rm", image, "--version").strip()
    label = _podman(
        "image",
        "inspect",
        "--format",
        '{{index .Labels "org.opencontainers.image.version"}}',
        image,
    ).strip()
    python = "import fastcs_ethercat as f; print(f.__version__)"
    inside = _podman("run", "--rm", "--entrypoint", "python", image, "-c", python)

    assert printed == f"fastcs-ethercat {RELEASE}"
    assert label == inside.strip() == RELEASE


def _example_values() -> dict[str, Any]:
    return yaml.safe_load(VALUES.read_text())["ioc-instance"]


def _config_text(prefix: str, sim: SimProcess) -> str:
    return yaml.safe_dump(
        {"prefix": prefix, "target": sim.pyads_ip, "ams_net_id": sim.net_id}
    )


def _exec(name: str, *command: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [PODMAN, "exec", name, *command], capture_output=True, text=True, timeout=30
    )


def _passes(name: str, command: list[str]) -> bool:
    return _exec(name, *command).returncode == 0


def _ioc_pid(name: str) -> str:
    """The IOC's PID inside the container (from its heartbeat file)."""
    return _exec(name, "cat", HEARTBEAT_FILE).stdout.split()[0]


def test_liveness_follows_the_ioc_not_the_plc_and_prestop_stops_it(
    image: str, tmp_path: Path, token: str
) -> None:
    env = ioc_env(token)
    prefix = f"LIV{token[:6].upper()}"
    name = f"fastcs-ethercat-live-{token}"
    values = _example_values()
    config_dir = tmp_path / "config"
    config_dir.mkdir()
    sim = SimProcess(chain=DEMO_CHAIN, env=env)
    sim.start()
    (config_dir / "ioc.yaml").write_text(_config_text(prefix, sim))
    ioc = _run(
        name,
        prefix,
        env,
        token,
        "--volume",
        f"{config_dir}:/epics/ioc/config:ro",
        "--entrypoint",
        values["command"][0],  # the example's command: the IOC under stdio-socket
        image,
        *values["args"],
    )
    try:
        ioc.wait_for_line("ioc ready", 120)
        serving = wait_for(lambda: _passes(name, LIVENESS), 30)
        sim.stop()  # the PLC goes away: an alarm, not a restart
        plc_gone = time.monotonic()
        without_plc = []
        while time.monotonic() - plc_gone < 25:  # past the 15 s heartbeat age
            without_plc.append(_passes(name, LIVENESS))
            time.sleep(5)
        pid = _ioc_pid(name)
        hang = _exec(name, "/bin/bash", "-c", f"kill -STOP {pid}")  # hung
        stopped = time.monotonic()
        failed = wait_for(lambda: not _passes(name, LIVENESS), 30)
        failed_in = time.monotonic() - stopped
        _exec(name, "/bin/bash", "-c", f"kill -CONT {pid}")
        resumed = wait_for(lambda: _passes(name, LIVENESS), 30)
        prestop = _exec(name, *PRESTOP)
        ioc.unread()
        output = "".join(ioc.output)
    finally:
        subprocess.run([PODMAN, "rm", "--force", name], capture_output=True)
        ioc.stop()
        sim.stop()
    print(f"\nliveness failed {failed_in:.1f} s after the IOC was stopped")

    assert serving and without_plc and all(without_plc)
    assert hang.returncode == 0, hang.stderr
    assert failed and failed_in < 30
    assert resumed
    assert prestop.returncode == 0, prestop.stdout + prestop.stderr
    assert "the IOC exited" in prestop.stdout
    assert "Traceback" not in output


def _pod_manifest(
    pod: str, prefix: str, sim: SimProcess, env: dict[str, str], image: str
) -> str:
    """A ConfigMap and a pod as the ioc-instance chart renders the example
    (command, args, liveness, preStop from its values.yaml; host network;
    the config mounted at /epics/ioc/config), on loopback."""
    values = _example_values()
    config_map = {
        "apiVersion": "v1",
        "kind": "ConfigMap",
        "metadata": {"name": f"{pod}-config"},
        "data": {"ioc.yaml": _config_text(prefix, sim)},
    }
    container = {
        "name": "ioc",
        "image": image,
        "command": values["command"],
        "args": values["args"],
        "livenessProbe": values["livenessProbe"],
        "lifecycle": values["lifecycle"],
        "stdin": True,
        "tty": True,
        "env": [
            {"name": k, "value": v} for k, v in env.items() if k.startswith("EPICS_")
        ]
        + [{"name": "HOME", "value": "/tmp"}, {"name": "IOC_PREFIX", "value": prefix}],
        "volumeMounts": [{"name": "config-volume", "mountPath": "/epics/ioc/config"}],
    }
    pod_spec = {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {"name": pod},
        "spec": {
            "hostNetwork": values["hostNetwork"],
            "terminationGracePeriodSeconds": 3,
            "restartPolicy": "Always",
            "containers": [container],
            "volumes": [
                {"name": "config-volume", "configMap": {"name": f"{pod}-config"}}
            ],
        },
    }
    return yaml.safe_dump_all([config_map, pod_spec])


def _caget(env: dict[str, str], pv: str) -> str | None:
    """The value `caget -t` prints for `pv`, None if it gave none."""
    done = subprocess.run(
        [str(BIN / "caget"), "-t", "-w", "5", pv],
        env=env,
        capture_output=True,
        text=True,
        timeout=30,
    )
    value = done.stdout.strip()
    return value if value and " " not in value else None


def _running(container: str) -> bool:
    state = subprocess.run(
        [PODMAN, "inspect", "--format", "{{.State.Status}}", container],
        capture_output=True,
        text=True,
    )
    return state.stdout.strip() == "running"


def test_pod_like_the_charts_stays_up_and_healthy_for_five_minutes(
    image: str, tmp_path: Path, token: str
) -> None:
    env = ioc_env(token)
    prefix = f"POD{token[:6].upper()}"
    pod = f"ecat-{token[:8].lower()}"
    container = f"{pod}-ioc"  # podman kube play: <pod>-<container>
    manifest = tmp_path / "pod.yaml"
    with SimProcess(chain=DEMO_CHAIN, env=env) as sim:
        manifest.write_text(_pod_manifest(pod, prefix, sim, env, image))
        _podman("kube", "play", str(manifest), timeout=120)
        heartbeat = f"{prefix}:HEARTBEAT"
        try:
            first = wait_for(lambda: _caget(env, heartbeat), 120)
            checks: list[tuple[bool, bool, str | None]] = []
            started = time.monotonic()
            while time.monotonic() - started < HEALTHY_FOR_S:
                health = subprocess.run(
                    [PODMAN, "healthcheck", "run", container],
                    capture_output=True,
                    text=True,
                )
                checks.append(
                    (
                        _running(container),
                        health.returncode == 0,
                        _caget(env, heartbeat),
                    )
                )
                time.sleep(15)
            restarts = _podman(
                "inspect", "--format", "{{.RestartCount}}", container
            ).strip()
            prestop = _exec(
                container, *_example_values()["lifecycle"]["preStop"]["exec"]["command"]
            )
        finally:
            subprocess.run(
                [PODMAN, "kube", "down", str(manifest)],
                capture_output=True,
                timeout=120,
            )
            subprocess.run(  # what a half-failed `kube play` leaves
                [PODMAN, "pod", "rm", "--force", pod], capture_output=True, timeout=120
            )
            subprocess.run(  # the ConfigMap's volume: podman 4's `kube down` keeps it
                [PODMAN, "volume", "rm", "--force", f"{pod}-config"],
                capture_output=True,
                timeout=120,
            )
            for pid in processes_with_token(token):
                stop_pid(pid)
    beats = [int(beat) for _, _, beat in checks if beat is not None]
    print(
        f"\npod healthy for {HEALTHY_FOR_S:.0f} s: {len(checks)} checks, "
        f"heartbeat {first} -> {beats[-1] if beats else None}"
    )

    assert first is not None
    assert checks and all(up and healthy for up, healthy, _ in checks), checks
    assert (
        len(beats) == len(checks) and beats == sorted(beats) and beats[-1] > int(first)
    )
    assert restarts == "0"
    assert prestop.returncode == 0 and "the IOC exited" in prestop.stdout
