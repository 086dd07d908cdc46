"""Shared helpers for tests that run an IOC in a subprocess.

An IOC under test always lives in its own process (softioc starts once per
process) with CA and PVA on free loopback ports of its own, so it cannot meet
another test's IOC. Real clients talk to it: the `caget`/`caput`/`pvget`
binaries of the venv (their wrappers always exit 0, so their output is what
counts), aioca (in a subprocess: its CA context is one per process) and p4p.
They all share the session's CA repeater (`tests/ca_repeater.py`), so none
spawns a caRepeater. Everything started is stopped by PID at the end,
including whatever the IOC spawned (found by a token in its environment).
"""

from __future__ import annotations

import contextlib
import re
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from p4p.client.thread import Context

from fastcs_ethercat.process import ChildProcess, free_port
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import TERMINALS_DIR, loopback_env
from tests.processes import (
    CLI,
    TOKEN_VARIABLE,
    new_token,
    processes_with_token,
    run_cli_child,
    run_python_child,
    stop_pid,
)

BIN = Path(sys.executable).parent
START_TIMEOUT = 90.0


def ioc_env(token: str) -> dict[str, str]:
    """Loopback EPICS settings on free ports, tagged with `token` (the CA
    repeater port is the session's)."""
    return loopback_env(
        EPICS_CA_SERVER_PORT=str(free_port(tcp=True, udp=True)),
        EPICS_PVA_SERVER_PORT=str(free_port(tcp=True, udp=False)),
        EPICS_PVA_BROADCAST_PORT=str(free_port(tcp=False, udp=True)),
        PYTHONUNBUFFERED="1",
        **{TOKEN_VARIABLE: token},
    )


@dataclass
class IocProcess:
    """An IOC child process (`process.ChildProcess`, stdout and stderr in
    one stream), its environment and the output read so far."""

    child: ChildProcess
    prefix: str
    env: dict[str, str]
    token: str
    output: list[str] = field(default_factory=list)
    """Lines read by `wait_for_line` and `unread`, each with its newline."""
    figures: dict[str, float] = field(default_factory=dict)

    def pv(self, name: str) -> str:
        return f"{self.prefix}:{name}"

    def unread(self) -> list[str]:
        """The lines that came since the last read, now read."""
        lines = [f"{line}\n" for line in self.child.lines[len(self.output) :]]
        self.output.extend(lines)
        return lines

    def wait_for_line(self, pattern: str, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            exited = self.child.returncode is not None
            for line in self.child.lines[len(self.output) :]:
                self.output.append(f"{line}\n")
                if re.search(pattern, line):
                    return f"{line}\n"
            if exited:
                break
            time.sleep(0.05)
        tail = "".join(self.output[-40:])
        raise AssertionError(f"no line matching {pattern!r}; output:\n{tail}")

    def tool(self, *args: str, timeout: float = 30) -> str:
        """Run a CA/PVA command-line tool against this IOC; return its output."""
        done = subprocess.run(
            [str(BIN / args[0]), *args[1:]],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        return done.stdout + done.stderr

    def p4p_context(self) -> Context:
        return Context(
            "pva",
            conf={
                "EPICS_PVA_ADDR_LIST": "127.0.0.1",
                "EPICS_PVA_AUTO_ADDR_LIST": "NO",
                "EPICS_PVA_BROADCAST_PORT": self.env["EPICS_PVA_BROADCAST_PORT"],
                "EPICS_PVA_SERVER_PORT": self.env["EPICS_PVA_SERVER_PORT"],
            },
            useenv=False,
        )

    def stop(self) -> int | None:
        """Stop the IOC and everything carrying its token, by PID; the IOC's
        exit code (negative: killed by that signal)."""
        code = self.child.stop()
        for pid in processes_with_token(self.token):
            stop_pid(pid)
        return code


def start_ioc(
    command: Sequence[str],
    prefix: str,
    env: dict[str, str],
    token: str,
    *,
    commands: bool = False,
) -> IocProcess:
    """Start `command`, its stdout and stderr read as one stream from now on;
    `commands`: with a pipe to its stdin (test IOCs that take commands)."""
    child = ChildProcess(
        command, "ioc", env=env, stdin_pipe=commands, merge_stderr=True
    )
    child.launch()
    return IocProcess(child, prefix, env, token)


def caget(ioc: IocProcess, *flags_and_names: str) -> dict[str, str]:
    """caget's `NAME VALUE...` lines as a dict (value: the rest of the line)."""
    output = ioc.tool("caget", *flags_and_names)
    values = {}
    for line in output.splitlines():
        name, _, value = line.partition(" ")
        if name.startswith(ioc.prefix):
            values[name] = value.strip()
    return values


def aioca_get(ioc: IocProcess, names: Sequence[str]) -> dict[str, str]:
    """Values read with aioca in a subprocess, as `repr` text by name."""
    script = (
        "import asyncio, aioca, sys\n"
        "async def main(names):\n"
        "    values = await aioca.caget(names, format=aioca.FORMAT_CTRL,"
        " timeout=10)\n"
        "    for name, value in zip(names, values):\n"
        "        print(name, repr(value.real if hasattr(value, 'real')"
        " else value))\n"
        "asyncio.run(main(sys.argv[1:]))\n"
    )
    done = run_python_child(script, *names, env=ioc.env, timeout=60)
    return dict(
        line.split(" ", 1)
        for line in done.stdout.splitlines()
        if line.startswith(ioc.prefix)
    )


def wait_for(check: Callable[[], Any], timeout: float = 10.0) -> Any:
    """Call `check` until it returns something true or `timeout` passes."""
    deadline = time.monotonic() + timeout
    while True:
        result = check()
        if result or time.monotonic() > deadline:
            return result
        time.sleep(0.1)


def parse_fields(text: str) -> dict[str, Any]:
    """`key=value` words of a line."""
    return dict(item.split("=", 1) for item in text.split() if "=" in item)


IOC_COMMAND: tuple[str, ...] = (*CLI, "ioc")


def write_ioc_config(
    folder: Path, prefix: str, target: str, ams_net_id: str, **settings: Any
) -> Path:
    """`folder/ioc.yaml` for an IOC of `target` (more keys in `settings`)."""
    config = folder / "ioc.yaml"
    config.write_text(
        yaml.safe_dump(
            {"prefix": prefix, "target": target, "ams_net_id": ams_net_id, **settings}
        )
    )
    return config


def list_pvs_text(config: Path, env: dict[str, str], *flags: str) -> str:
    """What `ioc --config CONFIG --list-pvs FLAGS...` prints."""
    done = run_cli_child("ioc", "--config", config, "--list-pvs", *flags, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    return done.stdout


def list_pvs(config: Path, env: dict[str, str], *flags: str) -> list[list[str]]:
    """The PV list as [name, access, type, source] rows (a source may hold
    spaces)."""
    text = list_pvs_text(config, env, *flags)
    return [line.split(" ", 3) for line in text.splitlines()]


def read_pvs_by_source(
    config: Path, env: dict[str, str], chain: Path | None = None
) -> dict[str, str]:
    """Source (TwinCAT symbol, `CoE:8000:11`, `ioc`) -> name of its first read
    PV, from `ioc --list-pvs` (of `chain` without the PLC, when given): tests
    find PVs by where their values come from, not by a naming pattern."""
    flags = ["--chain", str(chain)] if chain is not None else []
    found: dict[str, str] = {}
    for name, access, _, source in list_pvs(config, env, *flags):
        if access == "r":
            found.setdefault(source, name)
    return found


SELECTED_COE_OBJECT = "ai_settings_8000"
"""EL3104's `AI Settings` (0x8000): the CoE object test IOCs serve."""


def terminals_with_coe(target: Path, leave_out: Sequence[str] = ()) -> Path:
    """A copy of the repository's terminal YAML in `target` with EL3104's
    `SELECTED_COE_OBJECT` selected whole (the shipped file selects one of its
    sub-indices, `Enable filter`), and without the types in `leave_out`
    (served by the generic controller)."""
    target.mkdir()
    header = f"    fastcs_name: {SELECTED_COE_OBJECT}\n    selected: true\n"
    for path in TERMINALS_DIR.glob("*.yaml"):
        if path.stem in leave_out:
            continue
        text = path.read_text(encoding="utf-8")
        if path.stem == "EL3104":
            head, found, tail = text.partition(header)
            assert found, f"EL3104 no longer selects {SELECTED_COE_OBJECT}"
            block, next_object, rest = tail.partition("\n  - index:")
            block = block.replace("      selected: false\n", "")
            text = head + found + block + next_object + rest
        (target / path.name).write_text(text, encoding="utf-8")
    return target


@contextlib.contextmanager
def served_ioc(
    stem: str,
    chain: Path,
    write_config: Callable[[SimProcess, str], Path],
    *flags: str,
    sim_shares_ioc_env: bool = True,
) -> Iterator[tuple[SimProcess, IocProcess]]:
    """A simulator of `chain` and an IOC against it (prefix `stem` + token),
    ready; the IOC stopped (and everything carrying its token) afterwards.

    `sim_shares_ioc_env=False` keeps the simulator out of the IOC's token, so
    it outlives the IOC (to read its counters after the IOC stopped).
    """
    token = new_token()
    env = ioc_env(token)
    prefix = f"{stem}{token[:6].upper()}"
    sim_env = env if sim_shares_ioc_env else None
    with SimProcess(chain=chain, terminals=TERMINALS_DIR, env=sim_env) as sim:
        config = write_config(sim, prefix)
        command = [*IOC_COMMAND, "--config", str(config), *flags]
        ioc = start_ioc(command, prefix, env, token)
        try:
            ioc.wait_for_line("ioc ready", START_TIMEOUT)
            yield sim, ioc
        finally:
            ioc.stop()


def command(ioc: IocProcess, line: str) -> int:
    """Send one line to a test IOC that takes commands (`start_ioc(...,
    commands=True)`); the number it answers with."""
    stdin = ioc.child.stdin
    assert stdin is not None, "started without commands=True"
    stdin.write(line + "\n")
    stdin.flush()
    answer = ioc.wait_for_line(r"^(done|failed) ", 30)
    assert answer.startswith("done "), answer
    return int(answer.split()[2])
