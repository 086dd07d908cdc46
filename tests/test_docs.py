"""The documentation site: it builds with warnings as errors, and its
generated reference misses no command or option of the CLI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "docs" / "_ext"))
import reference_pages

SPHINX_BUILD = (
    sys.executable,
    "-m",
    "sphinx",
    "-W",
    "--keep-going",
    "-q",
    "-b",
    "html",
)
"""The README's build command: warnings are errors."""


def test_every_cli_command_and_option_has_help() -> None:
    assert reference_pages.undocumented_options() == []


def test_the_cli_page_lists_every_command_and_option() -> None:
    page = reference_pages.cli_page()
    for doc in reference_pages.walk_commands():
        assert f"`{doc.path}`" in page
        for param in doc.command.params:
            if param.param_type_name == "option" and not param.hidden:
                assert f"`{param.opts[0]}" in page, f"{doc.path} {param.opts[0]}"


def test_the_config_page_lists_every_key() -> None:
    from fastcs_ethercat.ioc.config import IocConfig

    page = reference_pages.config_page()
    for key in IocConfig.model_fields:
        assert f"| `{key}` |" in page, key


@pytest.mark.e2e
def test_the_site_builds_with_warnings_as_errors(tmp_path: Path) -> None:
    out = tmp_path / "html"
    done = subprocess.run(
        [*SPHINX_BUILD, str(REPO_ROOT / "docs"), str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    pages = {p.relative_to(out).as_posix() for p in out.rglob("*.html")}
    shipped = sorted(p.stem for p in (REPO_ROOT / "terminals").glob("*.yaml"))
    assert {f"reference/generated/terminals/{t}.html" for t in shipped} <= pages
    assert "reference/generated/cli.html" in pages
    el3104 = (out / "reference/generated/terminals/EL3104.html").read_text()
    assert "C8000:EnableFilter" in el3104
