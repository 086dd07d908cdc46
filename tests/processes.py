"""Processes the tests start: one way to run them, found by a token in their
environment, stopped by PID.

A process that runs alongside a test is a `fastcs_ethercat.process.
ChildProcess` (its output read as it comes, `wait_for_line` to wait for a
line of it); a one-shot run of the project's command line is
`run_cli_child`, the same command the console script runs, and a one-shot
Python client or probe `run_python_child`.

Every process a test starts inherits the session's token (the conftest puts
it in `os.environ`), and the processes of one IOC also carry a token of
their own; children they spawn themselves (a caRepeater, the simulator the
demo starts) inherit it as well, so they are found without knowing their
parents.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import signal
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from fastcs_ethercat.process import ChildProcess

CLI: Final = (sys.executable, "-m", "fastcs_ethercat")
"""`fastcs-ethercat` as its console script runs it (`__main__.main`)."""
CLI_TIMEOUT_S: Final = 120.0

TOKEN_VARIABLE = "FASTCS_ETHERCAT_TEST_TOKEN"
"""Carried by the processes of one IOC under test."""
SESSION_VARIABLE = "FASTCS_ETHERCAT_TEST_SESSION"
"""Carried by every process one pytest session starts."""


def new_token() -> str:
    return secrets.token_hex(8)


def processes_with(variable: str, token: str) -> list[int]:
    """PIDs, other than ours, whose environment has `variable=token`."""
    found = []
    marker = f"{variable}={token}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker in (entry / "environ").read_bytes().split(b"\0"):
                found.append(int(entry.name))
        except OSError:
            continue
    return found


def processes_with_token(token: str) -> list[int]:
    """PIDs of the processes of one IOC under test (its caRepeater too)."""
    return processes_with(TOKEN_VARIABLE, token)


def command_line(pid: int) -> str:
    """What a process runs, for messages ('' once it is gone)."""
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return ""
    return raw.replace(b"\0", b" ").decode(errors="replace").strip()


def running(pid: int) -> bool:
    """Whether `pid` still runs: a zombie (exited, not yet reaped by its
    parent, as our own children are until waited for) does not."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def stop_pid(pid: int) -> None:
    """SIGTERM, then SIGKILL after 5 s, one PID."""
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    deadline = time.monotonic() + 5
    while running(pid):
        if time.monotonic() > deadline:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            return
        time.sleep(0.05)


def run_cli_child(
    *args: str | Path,
    env: Mapping[str, str] | None = None,
    cwd: Path | None = None,
    timeout: float = CLI_TIMEOUT_S,
) -> subprocess.CompletedProcess[str]:
    """`fastcs-ethercat ARGS` in a child process, run to its end: its exit
    code, stdout and stderr as a user's shell would see them."""
    return subprocess.run(
        [*CLI, *map(str, args)],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def run_python_child(
    code: str,
    *args: str,
    env: Mapping[str, str] | None = None,
    timeout: float = CLI_TIMEOUT_S,
) -> subprocess.CompletedProcess[str]:
    """`python -c CODE ARGS` in a child process, run to its end: a client
    or probe that must not share this process's state (one CA context per
    process, EPICS' access security, the modules a command imports)."""
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def wait_for_line(child: ChildProcess, pattern: str, timeout: float) -> str:
    """The first line of `child`'s output matching `pattern` (`re.search`),
    once it came; AssertionError with the output's end if the child exits or
    `timeout` passes first."""
    deadline = time.monotonic() + timeout
    while True:
        exited = child.returncode is not None
        if exited:
            child.wait(5)  # its last lines read
        found = next((line for line in child.lines if re.search(pattern, line)), None)
        if found is not None:
            return found
        if exited or time.monotonic() > deadline:
            break
        time.sleep(0.02)
    raise AssertionError(f"no line matching {pattern!r}:\n{child.log_tail(2000)}")
