"""A git checkout of the working tree with a release tag, for the tests of
the version (setuptools-scm takes it from the tag): the files git would
commit now (tracked and new, not ignored), committed once and tagged."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

from tests.conftest import REPO_ROOT

_GIT_ID = ["-c", "user.name=test", "-c", "user.email=test@localhost"]


def _git(where: Path, *args: str) -> str:
    done = subprocess.run(
        ["git", *_GIT_ID, *args], cwd=where, capture_output=True, text=True
    )
    assert done.returncode == 0, f"git {' '.join(args)}: {done.stderr}"
    return done.stdout


def tagged_checkout(dest: Path, tag: str) -> Path:
    """`dest` holding the working tree as one commit tagged `tag`."""
    listed = _git(REPO_ROOT, "ls-files", "-z", "-co", "--exclude-standard")
    dest.mkdir(parents=True)
    for name in filter(None, listed.split("\0")):
        source = REPO_ROOT / name
        if source.is_symlink() or source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name, follow_symlinks=False)
    _git(dest, "init", "-q")
    _git(dest, "add", "-A")
    _git(dest, "commit", "-q", "-m", f"release {tag}")
    _git(dest, "tag", tag)
    return dest
