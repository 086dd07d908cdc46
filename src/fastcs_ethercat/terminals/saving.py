"""Write a terminal file the one way every tool does: canonical text, the old
file's comments kept, and nothing written when nothing changed."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from fastcs_ethercat.bounded import MAX_TERMINAL_YAML_BYTES, read_text_bounded
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.comments import DroppedComment, carry_comments
from fastcs_ethercat.terminals.files import terminal_file_text
from fastcs_ethercat.terminals.model import TerminalType


@dataclass(frozen=True)
class SavedFile:
    """What a save did to one file."""

    path: Path
    text: str
    changed: bool
    dropped: list[DroppedComment] = field(default_factory=list)


def old_text(path: Path) -> str | None:
    """The file's current text, None if there is no file yet."""
    if not path.exists():
        return None
    return read_text_bounded(path, MAX_TERMINAL_YAML_BYTES, what="terminal YAML file")


def file_text(
    terminals: Mapping[str, TerminalType], before: str | None
) -> tuple[str, list[DroppedComment]]:
    """The text to write in place of `before` (comments carried over)."""
    text = terminal_file_text(terminals)
    if before is None:
        return text, []
    return carry_comments(before, text)


def write_whole(path: Path, text: str) -> None:
    """Write `text` to a temporary file beside `path`, then rename it over
    `path`: a failure never leaves half a file behind."""
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        temporary.write_text(text, encoding="utf-8")
        os.replace(temporary, path)
    except OSError as error:
        temporary.unlink(missing_ok=True)
        raise UserError(f"cannot write: {error.strerror or error}", path=path) from None


def save_terminals(path: Path, terminals: Mapping[str, TerminalType]) -> SavedFile:
    """Write `terminals` to `path` unless the file already says exactly that."""
    before = old_text(path)
    text, dropped = file_text(terminals, before)
    changed = text != before
    if changed:
        write_whole(path, text)
    return SavedFile(path=path, text=text, changed=changed, dropped=dropped)
