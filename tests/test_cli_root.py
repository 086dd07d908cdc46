"""The root CLI: version and user-error handling."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fastcs_ethercat import __version__

pytestmark = pytest.mark.e2e


def test_version_flag_prints_version() -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "from fastcs_ethercat.cli import app; app()",
            "--version",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0
    assert done.stdout.strip() == f"fastcs-ethercat {__version__}"


def test_unknown_command_exits_nonzero_without_traceback() -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "from fastcs_ethercat.cli import app; app()",
            "no-such-command",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode != 0
    assert "Traceback" not in done.stderr
