"""Errors a user can act on.

Anything that comes from a user's input (a file, a flag, a target that does not
answer) is raised as `UserError`; the CLI prints its message as one line and
exits non-zero instead of showing a traceback.
"""

from __future__ import annotations

from pathlib import Path


class UserError(Exception):
    """A problem with the user's input, with a one-line message naming where."""

    exit_code: int = 2

    def __init__(
        self, message: str, *, path: Path | str | None = None, where: str | None = None
    ) -> None:
        parts = [str(p) for p in (path, where) if p not in (None, "")]
        prefix = ":".join(parts)
        one_line = " ".join(message.split())
        super().__init__(f"{prefix}: {one_line}" if prefix else one_line)
