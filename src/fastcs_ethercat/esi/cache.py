"""On-disk cache of catalog rows, keyed by the content of each ESI file.

Layout under `$XDG_CACHE_HOME/fastcs-ethercat/esi-catalog/` (default
`~/.cache/...`):

- `stat-index.json`: absolute path -> size, mtime_ns, sha256. A file whose
  size and mtime are unchanged is trusted to have the recorded sha256, so a
  warm listing reads no ESI bytes at all.
- `v<N>-<sha256>.json`: the catalog rows and warnings of one file (for a zip,
  of each member), valid for any path holding those bytes.

A cache that cannot be read or written is ignored: listing still works, only
slower. `CACHE_FORMAT` changes whenever the rows or the parser rules that
feed them change.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

from fastcs_ethercat.cache_dir import cache_dir

CACHE_FORMAT = 2


def cache_root() -> Path:
    """`$XDG_CACHE_HOME/fastcs-ethercat/esi-catalog` (XDG default ~/.cache)."""
    return cache_dir("esi-catalog")


def sha256_of(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _load_json(path: Path) -> Any:
    try:
        with path.open("rb") as handle:
            return json.load(handle)
    except (OSError, ValueError):
        return None


def _write_json(path: Path, value: Any) -> None:
    """Atomic write (temp file + rename); errors are swallowed on purpose."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, temp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".json")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                json.dump(value, handle, separators=(",", ":"))
            os.replace(temp, path)
        except BaseException:
            Path(temp).unlink(missing_ok=True)
            raise
    except OSError:
        pass


class CatalogCache:
    """Content-keyed store of per-file catalog data (see module docstring)."""

    def __init__(self, root: Path | None = None) -> None:
        self.root = root if root is not None else cache_root()
        self._index_path = self.root / "stat-index.json"
        loaded = _load_json(self._index_path)
        self._index: dict[str, dict[str, Any]] = (
            loaded if isinstance(loaded, dict) else {}
        )
        self._index_dirty = False

    def known_sha(self, path: Path) -> str | None:
        """sha256 recorded for `path` if its size and mtime are unchanged."""
        try:
            stat = path.stat()
        except OSError:
            return None
        record = self._index.get(str(path.resolve()))
        if (
            isinstance(record, dict)
            and record.get("size") == stat.st_size
            and record.get("mtime_ns") == stat.st_mtime_ns
        ):
            sha = record.get("sha256")
            return sha if isinstance(sha, str) else None
        return None

    def remember(self, path: Path, sha: str) -> None:
        """Record the sha256 of `path` under its current size and mtime."""
        try:
            stat = path.stat()
        except OSError:
            return
        self._index[str(path.resolve())] = {
            "size": stat.st_size,
            "mtime_ns": stat.st_mtime_ns,
            "sha256": sha,
        }
        self._index_dirty = True

    def _data_path(self, sha: str) -> Path:
        return self.root / f"v{CACHE_FORMAT}-{sha}.json"

    def load(self, sha: str) -> dict[str, Any] | None:
        """Cached per-member data of the file with this content, if any."""
        value = _load_json(self._data_path(sha))
        return value if isinstance(value, dict) else None

    def store(self, sha: str, value: dict[str, Any]) -> None:
        _write_json(self._data_path(sha), value)

    def flush(self) -> None:
        """Write the stat index if it changed."""
        if self._index_dirty:
            _write_json(self._index_path, self._index)
            self._index_dirty = False
