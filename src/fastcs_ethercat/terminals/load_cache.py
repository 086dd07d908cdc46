"""Validated terminal YAML files, cached on disk by their content.

Parsing the terminal YAML (every key's line kept, then pydantic and the
consistency checks) costs about 30 ms per file, over half a second for the 20
types in use at Diamond, on every IOC and simulator start. The validated
`TerminalType`s of a file are pickled under
`$XDG_CACHE_HOME/fastcs-ethercat/terminal-yaml/` (XDG default `~/.cache`),
keyed by the file's bytes and by the source of this package (the models and
the rules that build them), so an edited file or a changed model is parsed
again. Only files that loaded without error are cached: every error still
comes from the parser, with its line. A cache that cannot be read or written
is ignored.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
from functools import cache
from pathlib import Path

import pydantic

from fastcs_ethercat.bounded import MAX_TERMINAL_YAML_BYTES, read_bytes_bounded
from fastcs_ethercat.cache_dir import cache_dir
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import parse_terminal_text
from fastcs_ethercat.terminals.model import TerminalType

CACHE_FORMAT = 1


def cache_root() -> Path:
    """`$XDG_CACHE_HOME/fastcs-ethercat/terminal-yaml` (XDG default ~/.cache)."""
    return cache_dir("terminal-yaml")


@cache
def code_fingerprint() -> bytes:
    """The source of this package and pydantic's version: what the cached
    objects' shape depends on."""
    digest = hashlib.sha256(f"{CACHE_FORMAT} {pydantic.VERSION}".encode())
    for source in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(source.name.encode())
        digest.update(source.read_bytes())
    return digest.digest()


def read_terminal_file_cached(path: Path) -> dict[str, TerminalType]:
    """Like `files.read_terminal_file`, from the cache when the bytes match."""
    data = read_bytes_bounded(path, MAX_TERMINAL_YAML_BYTES, what="terminal YAML file")
    key = hashlib.sha256(code_fingerprint() + data).hexdigest()
    entry = cache_root() / f"v{CACHE_FORMAT}-{key}.pickle"
    cached = _load(entry)
    if cached is not None:
        return cached
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise UserError(f"cannot read: {error}", path=path) from None
    terminals = parse_terminal_text(text, path)
    _store(entry, terminals)
    return terminals


def _load(entry: Path) -> dict[str, TerminalType] | None:
    try:
        with entry.open("rb") as handle:
            value = pickle.load(handle)
    except Exception:  # a damaged or foreign entry is a miss: parse again
        return None
    if not isinstance(value, dict) or not all(
        isinstance(item, TerminalType) for item in value.values()
    ):
        return None
    return value


def _store(entry: Path, terminals: dict[str, TerminalType]) -> None:
    """Atomic write (temp file + rename); errors are swallowed on purpose."""
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        fd, temp = tempfile.mkstemp(dir=entry.parent, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as handle:
                pickle.dump(terminals, handle, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(temp, entry)
        except BaseException:
            Path(temp).unlink(missing_ok=True)
            raise
    except (OSError, pickle.PickleError, TypeError, AttributeError):
        pass
