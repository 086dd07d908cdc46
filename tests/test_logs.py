"""One log format for our modules and FastCS's loguru: time, level, source,
one line per event (a failed put included), tracebacks only at DEBUG."""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator

import pytest

from fastcs_ethercat.logs import LogLevel, log_at_most, setup_logging
from tests.processes import run_python_child

LINE = re.compile(
    r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3} (DEBUG|INFO|WARNING|ERROR|CRITICAL) +"
    r"[\w.]+: .+$"
)

# A failed put as FastCS logs it: loguru, with the exception and extras.
_FAILED_PUT = """
import sys
from fastcs_ethercat.logs import setup_logging
setup_logging(sys.argv[1])
import logging
from fastcs.logging import logger
logging.getLogger("fastcs_ethercat.ioc.app").info("discovered %d terminals", 104)
try:
    raise PermissionError("read-only IOC:\\nno ADS writes")
except PermissionError as error:
    logger.opt(exception=error).error("Put failed", attribute="AttrRW(Ch1)", setpoint=3)
logger.debug("not shown at info")
"""


def _run(level: str) -> list[str]:
    done = run_python_child(_FAILED_PUT, level)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    return done.stderr.splitlines()


@pytest.mark.e2e
def test_a_failed_put_is_one_line_with_time_level_and_source() -> None:
    lines = _run("info")

    assert len(lines) == 2
    assert all(LINE.match(line) for line in lines), lines
    assert " INFO    fastcs_ethercat.ioc.app: discovered 104 terminals" in lines[0]
    assert lines[1].endswith(
        " ERROR   fastcs: Put failed attribute=AttrRW(Ch1) setpoint=3: "
        "PermissionError: read-only IOC: no ADS writes"
    )


@pytest.mark.e2e
def test_debug_adds_the_traceback_without_local_variables() -> None:
    lines = _run("debug")
    text = "\n".join(lines)

    assert "Traceback (most recent call last)" in text
    assert "not shown at info" in text
    assert "setpoint = 3" not in text and "│" not in text  # no loguru variable dump


@pytest.mark.e2e
def test_warning_hides_info() -> None:
    lines = _run("WARNING")

    assert len(lines) == 1 and "Put failed" in lines[0]


@pytest.fixture
def records() -> Iterator[list[logging.LogRecord]]:
    root = logging.getLogger()
    saved = root.handlers[:], root.level
    setup_logging(LogLevel.INFO)
    seen: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append(record)

    root.addHandler(Keep())
    yield seen
    root.handlers[:], root.level = saved


def test_a_flood_becomes_a_few_lines_and_a_count(
    records: list[logging.LogRecord],
) -> None:
    logger = logging.getLogger("fastcs_ethercat.test")
    log_at_most(logger, logging.WARNING, [f"name {n}" for n in range(10_952)], 5,
                "PV names shortened (all of them at --log-level debug)")  # fmt: skip

    messages = [record.getMessage() for record in records]
    assert messages[:5] == [f"name {n}" for n in range(5)]
    assert messages[5:] == [
        "... and 10947 more PV names shortened (all of them at --log-level debug)"
    ]


def test_an_unknown_level_is_refused() -> None:
    with pytest.raises(ValueError, match="loud"):
        setup_logging("loud")


def test_a_level_set_for_a_module_holds_for_its_loguru_lines(
    records: list[logging.LogRecord],
) -> None:
    """How the audit leaves FastCS's put line (`fastcs.transports.epics.ca.ioc`,
    INFO) to DEBUG: loguru names the module, `logging` holds its level."""
    from fastcs.logging import logger

    module = logging.getLogger(__name__)
    module.setLevel(logging.WARNING)
    try:
        logger.info("PV put: X = 1")
        logger.warning("a warning of the same module")
    finally:
        module.setLevel(logging.NOTSET)
    logger.info("PV put: X = 2")

    shown = [(record.name, record.getMessage()) for record in records]
    assert shown == [
        ("fastcs", "a warning of the same module"),
        ("fastcs", "PV put: X = 2"),
    ]
