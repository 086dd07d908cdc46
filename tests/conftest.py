"""Shared test helpers: where things are, and the loopback-only EPICS env."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from fastcs_ethercat.loopback import EPICS_LOOPBACK_ENV as LOOPBACK

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_ESI = REPO_ROOT.parent / "shared" / "esi"
TERMINALS_DIR = REPO_ROOT / "terminals"
TEST_DATA = Path(__file__).resolve().parent / "data"

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
    """The real Beckhoff ESI files the project tests against."""
    assert SHARED_ESI.is_dir(), f"expected the shared ESI files at {SHARED_ESI}"
    return SHARED_ESI
