"""The Dockerfile's install steps, run in a fresh venv (CI has no Docker engine).

Also checks that the README's test command is exactly what CI runs.
"""

from __future__ import annotations

import re
import subprocess
import sys
import venv
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT


def _dockerfile_runs(stage: str) -> list[str]:
    """The RUN lines of one Dockerfile stage, to keep this test honest."""
    text = (REPO_ROOT / "Dockerfile").read_text()
    stages = re.split(r"^FROM ", text, flags=re.MULTILINE)
    body = next(s for s in stages if s.split("\n", 1)[0].endswith(f"AS {stage}"))
    return re.findall(r"^RUN (.*?)(?<!\\)$", body, flags=re.MULTILINE | re.DOTALL)


def test_dockerfile_is_multistage_nonroot_with_entrypoint() -> None:
    text = (REPO_ROOT / "Dockerfile").read_text()
    assert "AS build" in text and "AS runtime" in text
    assert re.search(r"^USER (?!root)\w+", text, flags=re.MULTILINE)
    assert 'ENTRYPOINT ["fastcs-ethercat"]' in text
    assert any("python -m build --wheel" in run for run in _dockerfile_runs("build"))
    assert any("pip install" in run for run in _dockerfile_runs("runtime"))


@pytest.mark.e2e
@pytest.mark.slow
def test_wheel_installs_into_fresh_venv_and_runs(tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "build", "--wheel", "--outdir", str(dist)],
        cwd=REPO_ROOT,
        check=True,
        capture_output=True,
    )
    wheels = list(dist.glob("fastcs_ethercat-*.whl"))
    assert len(wheels) == 1
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    subprocess.run(
        [str(env_dir / "bin" / "pip"), "install", "-q", str(wheels[0])],
        check=True,
        capture_output=True,
    )
    done = subprocess.run(
        [str(env_dir / "bin" / "fastcs-ethercat"), "--version"],
        check=True,
        capture_output=True,
        text=True,
    )
    assert done.stdout.startswith("fastcs-ethercat ")


def test_readme_test_command_is_what_ci_runs() -> None:
    readme = (REPO_ROOT / "README.md").read_text()
    ci_lines = (REPO_ROOT / ".ci" / "run").read_text().splitlines()
    command = ci_lines[-1].strip()
    assert command.startswith("python3 -m venv .venv")
    assert command in readme
