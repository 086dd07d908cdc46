"""Load terminal YAML from files, directories and glob patterns into a registry."""

from __future__ import annotations

import glob
from collections.abc import Iterable
from pathlib import Path

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import read_terminal_file
from fastcs_ethercat.terminals.load_cache import read_terminal_file_cached
from fastcs_ethercat.terminals.registry import RegisteredTerminal, TerminalRegistry

YAML_SUFFIXES = (".yaml", ".yml")
_GLOB_CHARACTERS = set("*?[")


def terminal_paths(sources: Iterable[Path | str]) -> list[Path]:
    """The YAML files named by files, directories (their *.yaml) and globs.

    Each file is listed once, in the order given (sorted within a directory
    or a glob). A name that matches nothing is a `UserError`.
    """
    found: list[Path] = []
    for source in sources:
        text = str(source)
        if _GLOB_CHARACTERS & set(text) and not Path(text).exists():
            matches = sorted(Path(m) for m in glob.glob(text, recursive=True))
            files = [m for m in matches if m.is_file()]
            if not files:
                raise UserError("no terminal YAML files match this pattern", path=text)
            found.extend(files)
            continue
        path = Path(text)
        if path.is_dir():
            found.extend(
                sorted(
                    p
                    for p in path.iterdir()
                    if p.suffix in YAML_SUFFIXES and p.is_file()
                )
            )
        elif path.is_file():
            found.append(path)
        else:
            raise UserError("no such terminal YAML file or directory", path=text)
    unique: dict[Path, None] = {}
    for path in found:
        unique.setdefault(path, None)
    return list(unique)


def load_terminals(
    sources: Iterable[Path | str], *, use_cache: bool = True
) -> TerminalRegistry:
    """Every terminal type in the named files (either YAML layout).

    Files already validated once come from the content-keyed cache
    (`load_cache`), unless `use_cache` is False."""
    read = read_terminal_file_cached if use_cache else read_terminal_file
    items = [
        RegisteredTerminal(type_name=name, terminal=terminal, path=path)
        for path in terminal_paths(sources)
        for name, terminal in read(path).items()
    ]
    return TerminalRegistry(items)
