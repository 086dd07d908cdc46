"""A first run as the README tells it: a fresh clone, README command 1, then
the line `demo` prints, pasted into a shell that has no EPICS settings at
all, reads a value.

The clone is of the committed HEAD (what a user would get). The demo is
given free ports of its own (a user's demo takes 5064 when free), and the
line it prints must carry them.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT
from tests.ioc_support import ioc_env, start_ioc
from tests.processes import (
    SESSION_VARIABLE,
    TOKEN_VARIABLE,
    new_token,
    processes_with_token,
    stop_pid,
)

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

DEMO_STEP = " && .venv/bin/fastcs-ethercat demo"


def readme_command_1() -> str:
    """The first bash block of the README's "Two commands" section."""
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("## Two commands", 1)[1]
    found = re.search(r"```bash\n(.+?)\n```", section, re.DOTALL)
    assert found, "README: no command in 'Two commands'"
    return found.group(1).strip()


def test_readme_command_1_installs_the_tools_and_runs_the_demo() -> None:
    command = readme_command_1()

    assert command.startswith("python3 -m venv .venv && ")
    assert command.endswith(DEMO_STEP)
    assert "[tools]" in command


def test_fresh_clone_command_1_then_the_printed_line_reads_a_value(
    tmp_path: Path,
) -> None:
    clone = tmp_path / "fastcs-ethercat"
    subprocess.run(
        ["git", "clone", "--quiet", str(REPO_ROOT), str(clone)],
        check=True,
        capture_output=True,
        timeout=120,
    )
    install = readme_command_1().removesuffix(DEMO_STEP)
    done = subprocess.run(
        ["bash", "-c", install], cwd=clone, capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr[-3000:]

    token = new_token()
    prefix = f"FR{token[:6].upper()}"
    demo = start_ioc(
        [str(clone / ".venv" / "bin" / "fastcs-ethercat"), "demo", "--prefix", prefix],
        prefix,
        ioc_env(token),
        token,
    )
    try:
        line = demo.wait_for_line(r"^demo: try .*/caget ", 120)
        pasted = line.split("demo: try", 1)[1].strip()
        bare_shell = {  # no EPICS settings but the session's one CA repeater
            "PATH": os.environ.get("PATH", "/usr/bin:/bin"),
            "HOME": str(tmp_path),
            "EPICS_CA_REPEATER_PORT": os.environ.get("EPICS_CA_REPEATER_PORT", ""),
            TOKEN_VARIABLE: token,
            SESSION_VARIABLE: os.environ.get(SESSION_VARIABLE, ""),
        }
        read = subprocess.run(
            ["bash", "-c", pasted],
            env=bare_shell,
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        demo.stop()
        for pid in processes_with_token(token):
            stop_pid(pid)

    name, _, value = read.stdout.strip().partition(" ")
    assert str(clone) in pasted  # the clone's own caget
    assert name == f"{prefix}:ETH1:RIO1:MOD5:CH1:Value", read.stdout + read.stderr
    assert -10.001 <= float(value.strip()) <= 10  # volts
