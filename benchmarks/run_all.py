"""Every benchmark of the issue in one go: `fastcs-ethercat bench` from here.

Usage: python benchmarks/run_all.py [--quick] [--json FILE] [--only SECTION ...]

Runs from the repository root whatever the working directory, so the defaults
(terminals/, ioc/demo-chain.yaml, ../shared/esi) are found.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
PATH_OPTIONS = ("--json", "--terminals", "--esi", "--demo-chain")


def main() -> None:
    from fastcs_ethercat.cli import app

    given = sys.argv[1:]
    # Paths given relative to where we were started stay right after the chdir.
    arguments = [
        str(Path(arg).resolve()) if previous in PATH_OPTIONS else arg
        for previous, arg in zip(["", *given[:-1]], given, strict=True)
    ]
    shared_esi = REPO_ROOT.parent / "shared" / "esi"
    if "--esi" not in arguments and shared_esi.is_dir():
        arguments += ["--esi", str(shared_esi)]  # the README's figures
    os.chdir(REPO_ROOT)
    sys.argv = ["fastcs-ethercat", "bench", *arguments]
    app()


if __name__ == "__main__":
    main()
