"""Shared test helpers: where things are, the loopback-only EPICS env, and the
session's guards (`tests/session_guards.py`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Final

import pytest

from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV as LOOPBACK
from tests.session_guards import pytest_configure as pytest_configure
from tests.session_guards import pytest_fixture_setup as pytest_fixture_setup
from tests.session_guards import pytest_runtest_makereport as pytest_runtest_makereport
from tests.session_guards import pytest_runtest_protocol as pytest_runtest_protocol
from tests.session_guards import pytest_sessionfinish as pytest_sessionfinish
from tests.session_guards import pytest_terminal_summary as pytest_terminal_summary
from tests.session_guards import pytest_unconfigure as pytest_unconfigure

REPO_ROOT = Path(__file__).resolve().parents[1]

DLS_TYPES: Final = (
    "EK1100", "EK1122", "EL1014", "EL1084", "EL1124", "EL1502", "EL2024",
    "EL2124", "EL3104", "EL3124", "EL3202", "EL3314", "EL3356-0010", "EL3602",
    "EL3702", "EL4134", "EL4732", "ELM3704-0000", "EP3174-0002", "EP4374-0002",
)  # fmt: skip
"""The terminal types in use at Diamond (the design's table): one YAML file
each in `terminals/`, every one in the demo chain."""
TERMINALS_DIR = REPO_ROOT / "terminals"
TEST_DATA = Path(__file__).resolve().parent / "data"

SHARED_ESI = REPO_ROOT.parent / "shared" / "esi"
"""The full set of real Beckhoff ESI files, beside the clone (not in it)."""
ESI_SUBSET = TEST_DATA / "esi" / "beckhoff"
"""The devices the tests use, cut from `SHARED_ESI` (see its README)."""
NEEDS_ESI_SUBSET = (
    "needs the Beckhoff ESI subset committed in tests/data/esi/beckhoff "
    "(`python -m tests.esi_subset SRC` writes it from the full set)"
)
"""Why a test that reads `ESI_SUBSET` skips when the folder is gone."""
EL3356_FIXTURE = TEST_DATA / "esi" / "EL3356-0010-fixture.xml"
"""A hand-written EL3356-0010: no public copy of its ESI exists."""
SCREENSHOTS = REPO_ROOT / "build" / "screenshots"
"""Where the editor's browser tests keep a screenshot of every page unless
$FASTCS_ETHERCAT_SCREENSHOTS names another folder (CI uploads this one)."""

#: Every EPICS process in tests runs with these: loopback only, no broadcast.
EPICS_LOOPBACK_ENV: dict[str, str] = dict(LOOPBACK)

# Set for this process too, so in-process clients (aioca, p4p) stay on loopback.
os.environ.update(EPICS_LOOPBACK_ENV)


def loopback_env(**extra: str) -> dict[str, str]:
    """The environment for a subprocess: ours plus the loopback EPICS settings."""
    env = dict(os.environ)
    env.update(EPICS_LOOPBACK_ENV)
    env.update(extra)
    return env


@pytest.fixture(scope="session")
def shared_esi() -> Path:
    """The full set of real ESI files, for tests about every device of it."""
    if not SHARED_ESI.is_dir():
        pytest.skip("needs the full Beckhoff ESI set in ../shared/esi")
    return SHARED_ESI
