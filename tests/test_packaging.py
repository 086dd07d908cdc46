"""The package as pip installs it: a wheel that carries the terminal types
and the demo, so `demo` and the default `terminal_dirs` work outside a
checkout; the Dockerfile's shape; the README's test command is CI's."""

from __future__ import annotations

import re
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT
from tests.tagged_checkout import tagged_checkout

RELEASE = "9.8.7"
"""The version of the tagged checkout the wheel is built from (tag v9.8.7)."""


def test_dockerfile_defaults_and_epics_containers_layout() -> None:
    text = (REPO_ROOT / "Dockerfile").read_text()

    assert "ARG BASE_IMAGE=python:3.11-slim" in text
    assert re.search(r"^USER (?!root)\w+", text, flags=re.MULTILINE)
    assert 'ENTRYPOINT ["fastcs-ethercat"]' in text
    assert 'CMD ["ioc", "--config", "/epics/ioc/config/ioc.yaml"]' in text
    assert "--require-hashes" in text and "deploy/requirements.lock" in text
    assert "/epics/opi" in text


@pytest.mark.e2e
@pytest.mark.slow
def test_wheel_carries_the_data_and_runs_outside_the_checkout(tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    checkout = tagged_checkout(tmp_path / "checkout", f"v{RELEASE}")
    subprocess.run(
        [sys.executable, "-m", "build", "--wheel", "--outdir", str(dist)],
        cwd=checkout,
        check=True,
        capture_output=True,
    )
    (wheel,) = dist.glob("fastcs_ethercat-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    subprocess.run(
        [str(env_dir / "bin" / "pip"), "install", "-q", str(wheel)],
        check=True,
        capture_output=True,
    )
    cli = str(env_dir / "bin" / "fastcs-ethercat")
    version = subprocess.run(
        [cli, "--version"], cwd=tmp_path, check=True, capture_output=True, text=True
    )
    where = subprocess.run(
        [
            str(env_dir / "bin" / "python"),
            "-c",
            "from fastcs_ethercat import shipped as s\n"
            "print(len(list(s.BUILTIN_TERMINALS_DIR.glob('*.yaml'))),"
            " s.DEMO_CHAIN.is_file())",
        ],
        cwd=tmp_path,
        check=True,
        capture_output=True,
        text=True,
    )

    shipped = len(list((REPO_ROOT / "terminals").glob("*.yaml")))
    assert "fastcs_ethercat/data/terminals/EL3104.yaml" in names
    assert "fastcs_ethercat/data/ioc/demo.yaml" in names
    assert any(name.endswith("licenses/LICENSE") for name in names)
    assert wheel.name.startswith(f"fastcs_ethercat-{RELEASE}-")  # the tag's
    assert version.stdout.strip() == f"fastcs-ethercat {RELEASE}"
    assert "fastcs_ethercat/_version.py" in names
    assert where.stdout.split() == [str(shipped), "True"]
