"""`fastcs-ethercat ioc` and `demo` as a user runs them (subprocesses).

`demo` starts the simulator and the IOC itself; the test pastes the lines
it prints (caget, pvget, caget -S for text) into a shell without EPICS
settings. Everything is stopped by PID, including the simulator the demo
started and the clients' caRepeater (they carry the test's token).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from fastcs_ethercat.terminals.loader import load_terminals
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import free_port, ioc_env, start_ioc
from tests.processes import (
    CLI,
    SESSION_VARIABLE,
    TOKEN_VARIABLE,
    new_token,
    run_cli_child,
    run_python_child,
)

pytestmark = pytest.mark.e2e

README_COE_EXAMPLE = ":ETH1:RIO21:MOD22:C8000:EnableFilter"
"""The README's CoE example (below the prefix): the demo serves it."""
TERMINAL_PV = re.compile(r"^(?P<terminal>[^:]+:ETH\d+:RIO\d+:MOD\d+):(?P<rest>.+)$")
TWINCAT_TERMINAL = re.compile(r"^Term \d+ \((?P<type>[^)]+)\)\.")
"""A symbol's source names its terminal: `Term 5 (EL3104).AI ...`."""
ANALOG_INPUT = re.compile(r"^(EL|ELM|EP)3\d")
"""Beckhoff's analog input types: EL3104, ELM3704-0000, EP3174-0002."""


def test_the_readme_names_the_coe_example() -> None:
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    assert f"DEMO{README_COE_EXAMPLE}" in readme


def test_the_demo_serves_one_coe_object_of_every_analog_input_type() -> None:
    """What the demo tutorial promises: each analog input type (EL3.., ELM3..,
    EP3..) with a CoE dictionary serves one CoE object, named in the text."""
    done = run_cli_child("ioc", "--config", "ioc/demo.yaml", "--chain",
                         "ioc/demo-chain.yaml", "--list-pvs", cwd=REPO_ROOT,
                         env=ioc_env(new_token()))  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    types: dict[str, str] = {}  # `DEMO:ETH1:RIO1:MOD5` -> `EL3104`
    coe: dict[str, set[str]] = {}  # `DEMO:ETH1:RIO1:MOD5` -> {`C8000:EnableFilter`}
    for line in done.stdout.splitlines():
        name, _access, _type, source = line.split(" ", 3)
        found = TERMINAL_PV.match(name)
        if found is None:  # the IOC's and the masters' own PVs
            continue
        symbol = TWINCAT_TERMINAL.match(source)
        if symbol:
            types[found["terminal"]] = symbol["type"]
        if source.startswith("CoE:"):
            pv = found["rest"].removesuffix("_RBV")
            coe.setdefault(found["terminal"], set()).add(pv)
    shipped = load_terminals([TERMINALS_DIR])
    analog = {
        type_name
        for type_name in types.values()
        if ANALOG_INPUT.match(type_name) and shipped.get(type_name).terminal.coe_objects
    }
    served: dict[str, set[str]] = {}
    for terminal, objects in coe.items():
        served.setdefault(types[terminal], set()).update(objects)
    tutorial = (REPO_ROOT / "docs" / "tutorials" / "demo.md").read_text()
    promise = " ".join(tutorial.split("The demo also serves one CoE", 1)[1].split())

    assert analog == {"EL3104", "EL3124", "EL3202", "EL3314", "EL3356-0010",
                      "EL3602", "ELM3704-0000", "EP3174-0002"}  # fmt: skip
    assert set(served) == analog
    for type_name in sorted(analog):
        [pv] = served[type_name]  # one CoE object of each type
        assert type_name in promise and f"`...:{pv}`" in promise, (type_name, pv)


def test_a_missing_config_is_one_error_line(tmp_path: Path) -> None:
    done = run_cli_child("ioc", "--config", tmp_path / "none.yaml", "--list-pvs",
                         cwd=REPO_ROOT, env=ioc_env(new_token()))  # fmt: skip

    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"error: {tmp_path / 'none.yaml'}: no such file"
    ]


IMPORTS_PROBE = """
import atexit, runpy, sys

def heavy():
    names = {name.split(".")[0] for name in sys.modules}
    print("imported:", *sorted(names & {"fastcs", "softioc", "p4p"}), file=sys.stderr)

atexit.register(heavy)
sys.argv[0] = "fastcs-ethercat"
runpy.run_module("fastcs_ethercat", run_name="__main__", alter_sys=True)
"""
"""`python -m fastcs_ethercat`, saying at exit which of FastCS, softioc and
p4p it imported."""


@pytest.mark.parametrize(
    ("config", "error"),
    [
        ("prefix: BL01:\n", "YAML syntax error"),
        ("prefix: BL01\ntarget: 127.0.0.1\npoll_rate_hz: -1\n", "poll_rate_hz"),
        ("prefix: BL01\ntarget: 127.0.0.1\nchain: none.yaml\n", "no such chain"),
    ],
    ids=["syntax", "value", "chain"],
)
def test_a_mistake_in_the_config_is_said_before_fastcs_is_imported(
    tmp_path: Path, config: str, error: str
) -> None:
    """FastCS, softioc and EPICS take 1-2 s of CPU to import: a mistake in the
    config (or in the chain file it names) is said before that."""
    path = tmp_path / "ioc.yaml"
    path.write_text(config)
    done = run_python_child(IMPORTS_PROBE, "ioc", "--config", str(path),
                            "--list-pvs", env=ioc_env(new_token()))  # fmt: skip

    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 2, done.stderr
    assert lines[0].startswith(f"error: {tmp_path}") and error in lines[0]
    assert lines[1] == "imported:"


def test_an_unsupported_fastcs_version_stops_the_ioc_in_one_line(
    tmp_path: Path,
) -> None:
    """FastCS's metadata says 0.99.0 (a dist-info ahead on the path): once its
    config is read, the IOC refuses before it imports FastCS, naming the
    package and both versions."""
    fake = tmp_path / "fastcs-0.99.0.dist-info"
    fake.mkdir()
    (fake / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: fastcs\nVersion: 0.99.0\n"
    )
    env = {**ioc_env(new_token()), "PYTHONPATH": str(tmp_path)}
    done = run_cli_child("ioc", "--config", "ioc/demo.yaml", cwd=REPO_ROOT, env=env)

    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "error: packages: fastcs 0.99.0 is installed, fastcs-ethercat supports "
        "fastcs>=0.14.2,<0.15: install the versions pyproject.toml names"
    ]


WAIT_PROBE = """
import gc, logging, os, runpy, sys

class Probe(logging.Handler):
    def emit(self, record):
        if "nothing to serve" in record.getMessage():
            plugins = os.environ.get("PYDANTIC_DISABLE_PLUGINS")
            print(f"probe: collector={gc.isenabled()} plugins={plugins!r}", flush=True)

logging.getLogger("fastcs_ethercat.ioc.boot").addHandler(Probe())
sys.argv[0] = "fastcs-ethercat"
runpy.run_module("fastcs_ethercat", run_name="__main__", alter_sys=True)
"""
"""`python -m fastcs_ethercat`, saying when the IOC waits for its PLC whether
the collector runs and what pydantic's plugin switch is."""


@pytest.mark.parametrize(
    ("environment", "plugins"),
    [({}, "__all__"), ({"PYDANTIC_DISABLE_PLUGINS": ""}, "")],
    ids=["default", "plugins-wanted"],
)
def test_the_ioc_waiting_for_its_plc_collects_garbage(
    tmp_path: Path, environment: dict[str, str], plugins: str
) -> None:
    """The collector is held through the IOC's imports (`collector.hold`),
    never through the wait for a PLC that may not come for days. Pydantic's
    plugins are off unless the environment says otherwise."""
    token = new_token()
    target = f"127.0.0.1:{free_port(tcp=True, udp=False)}"  # nobody answers
    env = {**ioc_env(token), "XDG_CACHE_HOME": str(tmp_path)}  # no kept chain
    env.pop("PYDANTIC_DISABLE_PLUGINS", None)
    env.update(environment)
    config = str(REPO_ROOT / "ioc" / "demo.yaml")
    command = [sys.executable, "-c", WAIT_PROBE, "ioc", "--config", config,
               "--target", target]  # fmt: skip
    ioc = start_ioc(command, "DEMO", env, token)
    try:
        line = ioc.wait_for_line(r"^probe: ", 90)
    finally:
        ioc.stop()

    assert line.strip() == f"probe: collector=True plugins={plugins!r}"


def test_a_bad_flag_value_names_the_flag() -> None:
    done = run_cli_child("ioc", "--config", "ioc/demo.yaml", "--poll-rate", "0",
                         "--list-pvs", cwd=REPO_ROOT,
                         env=ioc_env(new_token()))  # fmt: skip

    assert done.returncode == 2
    assert "poll_rate_hz (command line)" in done.stderr.splitlines()[-1]


def test_a_target_that_does_not_answer_is_a_user_error() -> None:
    done = run_cli_child("ioc", "--config", "ioc/demo.yaml", "--target",
                         "127.0.0.1:1", "--list-pvs", cwd=REPO_ROOT,
                         env=ioc_env(new_token()))  # fmt: skip

    assert done.returncode == 2
    assert (
        done.stderr.strip()
        .splitlines()[-1]
        .startswith("error: target: cannot discover the target:")
    )


def test_demo_prints_lines_that_read_numbers_and_text_from_a_bare_shell(
    tmp_path: Path,
) -> None:
    token = new_token()
    prefix = f"DM{token[:6].upper()}"
    demo = start_ioc([*CLI, "demo", "--prefix", prefix], prefix, ioc_env(token), token)
    try:
        listed = demo.wait_for_line(r"^demo: \d+ PVs listed in ", 90)
        lines = [demo.wait_for_line(r"^demo: (try|text) ", 30) for _ in range(3)]
        lines.append(lines[0].replace(":ETH1:RIO1:MOD5:CH1:Value", README_COE_EXAMPLE))
        bare_shell = {  # no EPICS settings but the session's one CA repeater
            "PATH": os.environ["PATH"],
            "HOME": str(tmp_path),
            "EPICS_CA_REPEATER_PORT": os.environ.get("EPICS_CA_REPEATER_PORT", ""),
            TOKEN_VARIABLE: token,
            SESSION_VARIABLE: os.environ.get(SESSION_VARIABLE, ""),
        }
        outputs = [
            subprocess.run(
                ["bash", "-c", line.split(" ", 2)[2].strip()],
                env=bare_shell,
                capture_output=True,
                text=True,
                timeout=60,
            ).stdout
            for line in lines
        ]
        listing = Path(listed.rsplit(" in ", 1)[1].strip())
        names = [row.split(" ", 1)[0] for row in listing.read_text().splitlines()]
    finally:
        demo.stop()

    pv = f"{prefix}:ETH1:RIO1:MOD5:CH1:Value"
    caget_out, pvget_out, text_out, coe_out = outputs
    assert coe_out.split() == [prefix + README_COE_EXAMPLE, "False"], coe_out
    assert caget_out.split()[0] == pv and -10.001 <= float(caget_out.split()[1]) <= 10
    assert pv in pvget_out
    assert text_out.split() == [f"{prefix}:ETH1:RIO1:MOD5:AlStateText", "OP"]
    assert pv in names and len(names) > 400
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    examples = set(re.findall(r"\bDEMO(:[\w:]+\w)", readme))
    assert README_COE_EXAMPLE in examples
    assert sorted(e for e in examples if prefix + e not in names) == []
    assert listing.parent.stat().st_mode & 0o777 == 0o700
