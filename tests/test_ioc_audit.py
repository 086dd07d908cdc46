"""The audit of puts: the ACF loaded marks every WRITE rule TRAPWRITE (what
EPICS's asTrapWrite, and so softioc's put log, needs), and C's stdout keeps
each put line whole; a caput's and a pvput's audit lines are checked against
the demo IOC (tests/test_ioc_demo.py)."""

from __future__ import annotations

import getpass
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fastcs_ethercat.ioc.audit import trapwrite_acf, trapwrite_text
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT
from tests.ioc_support import list_pvs, served_ioc, write_ioc_config

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
OUTPUT = "Term 24 (EP4374-0002).AO Outputs Channel 3"


def test_every_write_rule_becomes_trapwrite_and_nothing_else_changes() -> None:
    text = (
        "ASG(OUTPUTS) {\n"
        "    RULE(1, READ)\n"
        "    RULE(1, WRITE) { UAG(operators) }\n"
        "    RULE( 2 ,WRITE )\n"
        "    RULE(1, WRITE, NOTRAPWRITE) { UAG(robots) }\n"
        "}\n"
    )

    assert trapwrite_text(text) == (
        "ASG(OUTPUTS) {\n"
        "    RULE(1, READ)\n"
        "    RULE(1, WRITE, TRAPWRITE) { UAG(operators) }\n"
        "    RULE(2, WRITE, TRAPWRITE)\n"
        "    RULE(1, WRITE, NOTRAPWRITE) { UAG(robots) }\n"
        "}\n"
    )


def test_the_example_acf_is_audited_line_for_line(tmp_path: Path) -> None:
    example = REPO_ROOT / "ioc" / "access-example.acf"
    audited = trapwrite_acf(example, tmp_path)
    before = example.read_text().splitlines()
    after = audited.read_text().splitlines()

    assert len(after) == len(before)  # EPICS's errors keep their line numbers
    changed = [b for b, a in zip(before, after, strict=True) if a != b]
    assert changed and all("WRITE" in line for line in changed)
    assert "TRAPWRITE" in audited.read_text()


_PIECES = """
import ctypes, os
from fastcs_ethercat.ioc.audit import _line_buffered_c_stdout
_line_buffered_c_stdout()
libc = ctypes.CDLL(None)
libc.printf(b"operator@host ")  # as softioc's listener prints: a word at a time
libc.printf(b"X:Output.VAL")
os.write(1, b"another line\\n")  # another thread's output, meanwhile
libc.printf(b" 0 -> 1\\n")
"""


@pytest.mark.e2e
def test_a_put_line_printed_in_pieces_leaves_c_stdout_whole() -> None:
    """Under PYTHONUNBUFFERED (as the image runs), Python makes C's stdout
    unbuffered: each printf went out alone and other output split the
    audit's line (seen with a pvput)."""
    done = subprocess.run(
        [sys.executable, "-c", _PIECES],
        capture_output=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        check=True,
    )

    assert done.stdout == b"another line\noperator@host X:Output.VAL 0 -> 1\n"


@pytest.mark.e2e
def test_a_pvput_to_an_ioc_without_ca_is_audited(tmp_path: Path) -> None:
    """PV Access alone (no CA server) still goes through the database, and
    so through the audit."""

    def config(sim: SimProcess, prefix: str) -> Path:
        return write_ioc_config(
            tmp_path,
            prefix,
            sim.pyads_ip,
            sim.net_id,
            transports={"ca": False, "pva": True},
        )

    with served_ioc("AUDPVA", DEMO_CHAIN, config) as (_, ioc):
        [pv] = [
            name
            for name, access, _, source in list_pvs(tmp_path / "ioc.yaml", ioc.env)
            if source == OUTPUT and access == "rw"
        ]
        said = ioc.tool("pvput", pv, "77")
        line = ioc.wait_for_line(rf"{pv}\.VAL \S+ -> 77$", 10)

    assert line.startswith(f"{getpass.getuser()}@127.0.0.1 "), said + line
