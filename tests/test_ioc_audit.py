"""The audit of puts: the ACF loaded marks every WRITE rule TRAPWRITE (what
EPICS's asTrapWrite, and so softioc's put log, needs); a caput's audit line
is checked against the demo IOC (tests/test_ioc_demo.py)."""

from __future__ import annotations

from pathlib import Path

from fastcs_ethercat.ioc.audit import trapwrite_acf, trapwrite_text
from tests.conftest import REPO_ROOT


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
