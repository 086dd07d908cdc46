"""The test session's guards, which keep the test tiers honest.

- Every process the session starts carries a session token in its
  environment; whatever a test leaves running is stopped by PID at the end
  and fails the run.
- A test that starts a process (itself, or through a fixture it uses) but is
  not marked `e2e` fails.
- Every CA client of the session shares one loopback CA repeater
  (`tests/ca_repeater.py`), so none spawns a caRepeater of its own.

The conftest imports these hooks; they live here to keep it about paths.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Generator
from typing import Any

import pytest

from tests.ca_repeater import LoopbackRepeater
from tests.processes import (
    SESSION_VARIABLE,
    command_line,
    new_token,
    processes_with,
    stop_pid,
)

_repeater: list[LoopbackRepeater] = []
_running_test: list[str] = [""]
"""The node id of the test being set up, run or torn down ('' between)."""
_started: dict[str, list[str]] = {}
"""Node id -> the commands that test (or a fixture it set up) started."""
_fixtures_starting: dict[tuple[str, str], str] = {}
"""(fixture name, base node id) -> the first command that fixture started, so
that every test using a module's simulator counts, not the first only."""


def pytest_configure(config: pytest.Config) -> None:
    """Tag every process of the session, give it a CA repeater, and note
    which test starts a process."""
    os.environ[SESSION_VARIABLE] = new_token()
    repeater = LoopbackRepeater().start()
    _repeater.append(repeater)
    os.environ["EPICS_CA_REPEATER_PORT"] = str(repeater.port)
    _record_process_starts()


def pytest_unconfigure(config: pytest.Config) -> None:
    while _repeater:
        _repeater.pop().close()


def _record_process_starts() -> None:
    original = subprocess.Popen.__init__
    if getattr(original, "records_starts", False):
        return

    def recording_init(
        self: subprocess.Popen[Any], args: Any, *more: Any, **kw: Any
    ) -> None:
        if _running_test[0]:
            words = [args] if isinstance(args, str | bytes | os.PathLike) else args
            command = " ".join(map(str, words))
            _started.setdefault(_running_test[0], []).append(command)
        original(self, args, *more, **kw)

    recording_init.records_starts = True  # type: ignore[attr-defined]
    subprocess.Popen.__init__ = recording_init  # type: ignore[method-assign]


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item) -> Generator[None, object, object]:
    _running_test[0] = item.nodeid
    try:
        return (yield)
    finally:
        _running_test[0] = ""


@pytest.hookimpl(wrapper=True)
def pytest_fixture_setup(
    fixturedef: pytest.FixtureDef[Any], request: pytest.FixtureRequest
) -> Generator[None, object, object]:
    before = len(_started.get(_running_test[0], []))
    try:
        return (yield)
    finally:
        started = _started.get(_running_test[0], [])[before:]
        if started:
            key = (fixturedef.argname, fixturedef.baseid)
            _fixtures_starting.setdefault(key, started[0])


def _processes_started_by(item: pytest.Item) -> list[str]:
    names = getattr(item, "fixturenames", ())
    return _started.get(item.nodeid, []) + [
        command
        for (name, base), command in _fixtures_starting.items()
        if name in names and item.nodeid.startswith(base)
    ]


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    """Fail a passing test that started a process (itself or through its
    fixtures) but is not marked `e2e`."""
    report = yield
    started = _processes_started_by(item)
    if (
        call.when == "call"
        and started
        and report.passed
        and item.get_closest_marker("e2e") is None
    ):
        report.outcome = "failed"
        report.longrepr = f"started a process but is not marked e2e: {started[0]}"
    return report


_left_running: list[tuple[int, str]] = []
"""(PID, command line) of each process the tests left running."""


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Stop, by PID, whatever a test left running, and fail the session."""
    token = os.environ[SESSION_VARIABLE]
    _left_running.extend(
        (pid, command_line(pid)) for pid in processes_with(SESSION_VARIABLE, token)
    )
    for pid, _ in _left_running:
        stop_pid(pid)
    if _left_running and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if _left_running:
        terminalreporter.write_sep("=", "left running by the tests, now stopped")
        for pid, command in _left_running:
            terminalreporter.write_line(f"pid {pid}: {command}", red=True)
