"""What a beamline deploys: the IOC config schema and the examples that use
it, the epics-containers instance, the lock the image installs from, the CI
workflow, the licence and the build context."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import jsonschema
import pytest
import yaml
from packaging.requirements import Requirement

from fastcs_ethercat.ioc.config import config_schema_text, load_ioc_config
from tests.conftest import REPO_ROOT, SCREENSHOTS
from tests.processes import run_cli_child

SCHEMA_FILE = REPO_ROOT / "ioc" / "ioc.schema.json"
DEPLOY = REPO_ROOT / "deploy"
INSTANCE = DEPLOY / "services" / "bl01t-ea-ecat-01"
VALUES_SCHEMA = DEPLOY / "ioc-instance.values.schema.json"
IOC_CONFIGS = sorted(
    [p for p in (REPO_ROOT / "ioc").glob("*.yaml") if not p.stem.endswith("-chain")]
    + list(DEPLOY.glob("services/*/config/ioc.yaml"))
)
SCHEMA_LINE = re.compile(r"^# yaml-language-server: \$schema=(\S+)$", re.MULTILINE)


def _schema_of(path: Path) -> Path:
    found = SCHEMA_LINE.search(path.read_text(encoding="utf-8"))
    assert found, f"{path}: no yaml-language-server $schema line"
    return (path.parent / found.group(1)).resolve()


def _yaml(path: Path) -> Any:
    return yaml.safe_load(path.read_text(encoding="utf-8"))


@pytest.mark.e2e
def test_the_committed_schema_is_what_ioc_schema_prints() -> None:
    done = run_cli_child("ioc", "schema")
    assert done.returncode == 0, done.stderr
    printed = done.stdout

    assert printed == config_schema_text() == SCHEMA_FILE.read_text(encoding="utf-8")
    jsonschema.Draft202012Validator.check_schema(json.loads(printed))


def test_there_are_examples_and_an_instance_config() -> None:
    names = {path.relative_to(REPO_ROOT).as_posix() for path in IOC_CONFIGS}

    assert {"ioc/demo.yaml", "ioc/beamline-example.yaml"} <= names
    assert (INSTANCE / "config" / "ioc.yaml").relative_to(REPO_ROOT).as_posix() in (
        names
    )


@pytest.mark.parametrize("path", IOC_CONFIGS, ids=lambda p: p.name)
def test_every_ioc_config_names_the_schema_validates_and_loads(path: Path) -> None:
    schema = json.loads(_schema_of(path).read_text(encoding="utf-8"))

    assert _schema_of(path) == SCHEMA_FILE.resolve()
    jsonschema.validate(_yaml(path), schema)
    assert load_ioc_config(path).prefix


def test_the_schema_rejects_what_the_loader_rejects() -> None:
    schema = json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    bad = {"prefix": "X", "target": "h", "poll_rate_hz": 0, "read_onyl": True}

    errors = list(jsonschema.Draft202012Validator(schema).iter_errors(bad))

    assert len(errors) == 2


def test_the_instance_follows_epics_containers() -> None:
    config = load_ioc_config(INSTANCE / "config" / "ioc.yaml")
    values = _yaml(INSTANCE / "values.yaml")
    instance = values["ioc-instance"]
    mounts = {m["name"]: m["mountPath"] for m in instance["volumeMounts"]}
    secrets = {v["name"]: v["secret"]["secretName"] for v in instance["volumes"]}

    assert config.screens_dir == Path("/epics/opi")
    assert config.route is not None and config.route.password_file is not None
    assert config.route.password_file.parent == Path(mounts["twincat-route"])
    assert secrets["twincat-route"].startswith(INSTANCE.name)
    assert instance["hostNetwork"] is True
    assert instance["command"] == ["stdio-socket"]
    assert "--config /epics/ioc/config/ioc.yaml" in instance["args"][-1]


def test_the_values_use_only_keys_the_chart_documents() -> None:
    values_path = INSTANCE / "values.yaml"
    schema = json.loads(VALUES_SCHEMA.read_text(encoding="utf-8"))

    assert _schema_of(values_path) == VALUES_SCHEMA.resolve()
    jsonschema.validate(_yaml(values_path), schema)
    with pytest.raises(jsonschema.ValidationError, match="memroy"):
        jsonschema.validate({"ioc-instance": {"image": "x", "memroy": "1Gi"}}, schema)


def test_resources_hold_the_measured_ioc() -> None:
    resources = _yaml(INSTANCE / "values.yaml")["ioc-instance"]["resources"]

    def mebibytes(text: str) -> int:
        number, unit = text[:-2], text[-2:]
        assert number.isdecimal() and unit in ("Mi", "Gi"), text
        return int(number) * (1024 if unit == "Gi" else 1)

    measured_demo_mb = 326  # VmRSS of the demo IOC, 24 terminals
    assert mebibytes(resources["requests"]["memory"]) >= measured_demo_mb
    assert mebibytes(resources["limits"]["memory"]) >= 519  # 500 terminals


def _normal(name: str) -> str:
    """A package name as PyPI compares them (PEP 503)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def test_the_lock_pins_every_dependency_within_its_bounds() -> None:
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    wanted = [Requirement(text) for text in project["dependencies"]]
    wanted += [Requirement(t) for t in project["optional-dependencies"]["tools"]]
    lock_text = (DEPLOY / "requirements.lock").read_text(encoding="utf-8")
    pins = {
        _normal(name): version
        for name, version in re.findall(
            r"^([A-Za-z0-9_.-]+)==(\S+) \\", lock_text, re.M
        )
    }

    for requirement in wanted:
        name = _normal(requirement.name)
        assert name in pins, f"{name} is not in deploy/requirements.lock"
        assert requirement.specifier.contains(pins[name]), (requirement, pins[name])
    assert "--hash=sha256:" in lock_text


@pytest.mark.e2e
def test_the_ci_workflow_is_valid_offline() -> None:
    checker = Path(sys.executable).parent / "check-jsonschema"
    workflows = sorted((REPO_ROOT / ".github" / "workflows").glob("*.yml"))

    done = subprocess.run(
        [
            str(checker),
            "--builtin-schema",
            "vendor.github-workflows",
            *map(str, workflows),
        ],
        capture_output=True,
        text=True,
    )

    assert workflows
    assert done.returncode == 0, done.stdout + done.stderr


def test_ci_keeps_the_editor_screenshots_of_every_run() -> None:
    workflow = _yaml(REPO_ROOT / ".github" / "workflows" / "ci.yml")
    steps = workflow["jobs"]["test"]["steps"]
    tests = next(i for i, step in enumerate(steps) if "pytest" in step.get("run", ""))
    uploads = [
        step
        for step in steps[tests + 1 :]
        if step.get("uses", "").startswith("actions/upload-artifact@")
    ]

    assert "FASTCS_ETHERCAT_SCREENSHOTS" not in str(steps[tests])  # the default
    [upload] = uploads
    assert upload["if"] == "always()"  # a failing run's screenshots above all
    folder = SCREENSHOTS.relative_to(REPO_ROOT).as_posix()
    assert upload["with"]["path"].rstrip("/") == folder


def _dockerfile_stages(text: str) -> dict[str, str]:
    """The Dockerfile's text by stage name (`FROM ... AS name`)."""
    stages = re.split(r"^FROM ", text, flags=re.MULTILINE)[1:]
    return {stage.split("\n", 1)[0].split()[-1]: stage for stage in stages}


def test_ci_builds_the_image_with_the_version_of_the_tag() -> None:
    """The build context has no .git (.dockerignore): without the VERSION
    build argument the image's wheel and label say 0+unknown, not the tag."""
    workflow = _yaml(REPO_ROOT / ".github" / "workflows" / "ci.yml")
    steps = workflow["jobs"]["image"]["steps"]
    runs = [step.get("run", "") for step in steps]
    [checkout] = [s for s in steps if s.get("uses", "").startswith("actions/checkout")]
    [versioned] = [i for i, run in enumerate(runs) if "setuptools_scm" in run]
    [built] = [i for i, run in enumerate(runs) if "docker build" in run]
    [smoke] = [run for run in runs if "--version" in run]
    dockerfile = (REPO_ROOT / "Dockerfile").read_text(encoding="utf-8")
    stages = _dockerfile_stages(dockerfile)
    how_to = (REPO_ROOT / "docs" / "how-to" / "deploy.md").read_text(encoding="utf-8")

    assert checkout["with"]["fetch-depth"] == 0  # the tags
    assert '"VERSION=$(python -m setuptools_scm)" >> "$GITHUB_ENV"' in runs[versioned]
    assert versioned < built
    assert '--build-arg VERSION="$VERSION"' in runs[built]
    assert '= "fastcs-ethercat $VERSION"' in smoke
    assert "ARG VERSION\n" in stages["wheels-index"]
    assert "SETUPTOOLS_SCM_PRETEND_VERSION=${VERSION}" in stages["wheels-index"]
    assert "ARG VERSION\n" in stages["runtime"]
    assert 'org.opencontainers.image.version="${VERSION}"' in stages["runtime"]
    for text in (how_to, dockerfile):  # what they suggest: v1.4.0 is no version
        assert "VERSION=$(git describe" not in text
        assert "VERSION=$(python -m setuptools_scm)" in text


def test_licence_and_build_context() -> None:
    licence = (REPO_ROOT / "LICENSE").read_text(encoding="utf-8")
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
    ignored = (REPO_ROOT / ".dockerignore").read_text(encoding="utf-8").splitlines()

    assert "Apache License" in licence and "Version 2.0" in licence
    assert project["project"]["license"] == "Apache-2.0"
    assert ignored[ignored.index("*") + 1 :][0].startswith("!")  # allow-list only
    assert "!.venv" not in ignored and "!build/wheelhouse/" in ignored
