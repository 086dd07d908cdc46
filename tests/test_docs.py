"""The documentation site: it builds with warnings as errors, and its
generated reference misses no command or option of the CLI."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from fastcs_ethercat.ioc.config import IocConfig
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
README_MAX_LINES = 200
"""The README is the front door (what it is, two commands, an example,
links); the rest lives in docs/."""


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


def test_the_readmes_example_config_is_valid() -> None:
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("## An example", 1)[1]
    found = re.search(r"```yaml\n(.+?)\n```", section, re.DOTALL)
    assert found, "README: no YAML in 'An example'"
    config = IocConfig.model_validate(yaml.safe_load(found.group(1)))
    assert config.prefix == "BL21I-EA-ECAT-01" and config.route is not None


def test_the_readme_is_a_front_door() -> None:
    """Short, both commands in "Two commands" (set up and run the demo; set up
    and run the tests, as `.ci/run` does), every link to a file that exists."""
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("\n## Two commands\n", 1)[1].split("\n## ", 1)[0]
    demo, tests = re.findall(r"```bash\n(.+?)\n```", section, re.DOTALL)
    ci_run = (REPO_ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    links = re.findall(r"\]\(([^)#]+)\)", readme)

    assert len(readme.splitlines()) <= README_MAX_LINES
    assert demo.startswith("python3 -m venv .venv && .venv/bin/pip install ")
    assert demo.endswith(" && .venv/bin/fastcs-ethercat demo")
    assert [line for line in ci_run if line.startswith("python3 -m venv")] == [tests]
    assert tests.endswith(" && .venv/bin/pytest")
    assert any(link.startswith("docs/") for link in links)
    missing = [
        link for link in links if "://" not in link and not (REPO_ROOT / link).exists()
    ]
    assert missing == []
