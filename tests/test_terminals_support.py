"""Shared helpers of the terminals tests (no tests here).

`run_cli` runs the real `fastcs-ethercat` entry point in-process (argv,
stdout, stderr and the exit code as a user would see them); `ESI` and
`FIXTURE` are the real Beckhoff files (the devices the tests use, cut from
them) and the EL3356-0010 fixture.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from fastcs_ethercat.cli import app
from fastcs_ethercat.esi.catalog import EsiCatalog, build_catalog
from tests.conftest import EL3356_FIXTURE as FIXTURE
from tests.conftest import ESI_SUBSET as ESI
from tests.conftest import NEEDS_ESI_SUBSET, TERMINALS_DIR

TERMINALS = TERMINALS_DIR
ESI_ARGS = ["--esi", str(ESI), "--esi", str(FIXTURE)]
needs_esi = pytest.mark.skipif(not ESI.is_dir(), reason=NEEDS_ESI_SUBSET)


@dataclass(frozen=True)
class CliResult:
    code: int
    out: str
    err: str


def run_cli(*args: str) -> CliResult:
    """Run `fastcs-ethercat <args>` in this process, as the console script does."""
    out, err = io.StringIO(), io.StringIO()
    saved = sys.argv
    sys.argv = ["fastcs-ethercat", *args]
    code = 0
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            app()
    except SystemExit as done:
        code = done.code if isinstance(done.code, int) else 1
    finally:
        sys.argv = saved
    return CliResult(code, out.getvalue(), err.getvalue())


@contextlib.contextmanager
def cache_home(path: Path) -> Iterator[None]:
    """XDG_CACHE_HOME pointed at `path` (catalog cache, ESI zip) for a while."""
    before = os.environ.get("XDG_CACHE_HOME")
    os.environ["XDG_CACHE_HOME"] = str(path)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("XDG_CACHE_HOME", None)
        else:
            os.environ["XDG_CACHE_HOME"] = before


def real_catalog() -> EsiCatalog:
    """The catalog of the real ESI files plus the EL3356-0010 fixture."""
    return build_catalog([ESI, FIXTURE], use_cache=False)


def regenerated_old_el3104(
    folder: Path, cache: Path, edit: Callable[[Path], object]
) -> tuple[Path, CliResult]:
    """EL3104 generated at its older revision 0x00100000 into `folder`, edited
    by `edit(path)`, then regenerated: the file and the regenerate result."""
    with cache_home(cache):
        made = run_cli("terminals", "generate", "EL3104", "--revision", "0x00100000",
                       *ESI_ARGS, "--out", str(folder))  # fmt: skip
        assert made.code == 0, made.err
        path = folder / "EL3104.yaml"
        edit(path)
        return path, run_cli("terminals", "regenerate", str(folder), *ESI_ARGS)
