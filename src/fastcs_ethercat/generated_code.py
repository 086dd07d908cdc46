"""The code dataclasses, named tuples and type hints generate, compiled once.

Creating a class compiles source text the standard library writes for it:
`@dataclass` its `__init__`, `__repr__`, `__eq__`, ... (one `exec` each),
`NamedTuple` its `__new__` (`eval`), and every string annotation that
`typing` resolves its `ForwardRef` (`compile`). The IOC's start creates ~200
dataclasses of its own, FastCS's and pydantic's: about 2 000 compiles of the
same text at every start, a tenth of the CPU before it talks to the PLC.

`cache_generated_code()` gives those three modules an `exec`, `eval` and
`compile` that first look the code up by its text, in a file of the cache
directory (`cache_dir`, one per interpreter bytecode version), until
`settle_generated_code()` writes back what was compiled anew and gives the
modules their builtins back: the CLI's entry point when its command returns,
the IOC as soon as it serves. A
code object is what the builtin compiles from the same text with the same
flags, so every class is the one it would have been; a damaged or foreign
file only costs the compiles again. The file is trusted as the user's own,
like the terminal-YAML cache beside it.

No `from __future__ import annotations` here: a builtin called from this
module inherits its future flags, and the modules it stands in for have none.
"""

import builtins
import collections
import dataclasses
import marshal
import os
import sys
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from fastcs_ethercat.cache_dir import cache_dir

_STAND_INS: Final = ((dataclasses, "exec"), (collections, "eval"), (typing, "compile"))
"""(module, the builtin whose generated code is cached in it)."""
MAX_ENTRIES: Final = 20_000
"""Entries kept at most: beyond, a save keeps only what its process used
(the file does not grow with every version of every class)."""
_ANONYMOUS: Final = "<string>"
"""The file name `exec` and `eval` give code they compile from text."""

_Key = tuple[str, str]
"""(mode, source text)."""


class _GeneratedCode:
    """The code by its text, what this process used, what it compiled."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.code = _read(path)
        self.used: set[_Key] = set()
        self.compiled = 0

    def lookup(self, mode: str, source: str) -> types.CodeType:
        key = (mode, source)
        code = self.code.get(key)
        if not isinstance(code, types.CodeType):
            code = builtins.compile(source, _ANONYMOUS, mode, dont_inherit=True)
            self.code[key] = code
            self.compiled += 1
        self.used.add(key)
        return code

    def save(self) -> None:
        """Write the file again if this process compiled anything."""
        if not self.compiled:
            return
        kept = self.code
        if len(kept) > MAX_ENTRIES:
            kept = {key: kept[key] for key in self.used}
        import tempfile  # only when writing

        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(
                dir=self.path.parent, prefix=f".{self.path.name}."
            )
            try:
                with os.fdopen(handle, "wb") as file:
                    marshal.dump(kept, file)
                os.replace(temporary, self.path)
            except BaseException:
                Path(temporary).unlink(missing_ok=True)
                raise
        except OSError:  # a read-only or full cache only costs the compiles
            return
        self.compiled = 0


def _read(path: Path) -> dict[_Key, Any]:
    try:
        with path.open("rb") as file:
            data = marshal.load(file)
    except (OSError, EOFError, ValueError, TypeError):
        return {}
    return data if isinstance(data, dict) else {}


def cache_path() -> Path:
    """The cache file of this interpreter's bytecode version and -O level."""
    tag = f"{sys.implementation.cache_tag}-O{sys.flags.optimize}"
    return cache_dir("generated-code") / f"{tag}.marshal"


def _run(cache: _GeneratedCode, mode: str) -> Callable[..., Any]:
    """`exec` or `eval` of generated text from the cache."""
    builtin = getattr(builtins, mode)

    def run(source: Any, /, *args: Any, **kwargs: Any) -> Any:
        if type(source) is str:
            source = cache.lookup(mode, source)
        return builtin(source, *args, **kwargs)

    run.__name__ = run.__qualname__ = mode
    return run


def _compile(cache: _GeneratedCode) -> Callable[..., Any]:
    def compile(
        source: Any,
        filename: Any,
        mode: str,
        flags: int = 0,
        dont_inherit: bool = False,
        optimize: int = -1,
    ) -> Any:
        plain = not flags and optimize == -1
        if type(source) is str and filename == _ANONYMOUS and plain:
            return cache.lookup(mode, source)
        return builtins.compile(source, filename, mode, flags, dont_inherit, optimize)

    return compile


_active: _GeneratedCode | None = None
_stood_in: list[tuple[types.ModuleType, str]] = []


def cache_generated_code(path: Path | None = None) -> None:
    """From now on, generated code comes from the cache file at `path`
    (default `cache_path()`) when it has it; once per process."""
    global _active
    if _active is not None:
        return
    _active = cache = _GeneratedCode(path or cache_path())
    for module, name in _STAND_INS:
        if name not in module.__dict__:  # a name of its own: leave it be
            stand_in = _compile(cache) if name == "compile" else _run(cache, name)
            setattr(module, name, stand_in)
            _stood_in.append((module, name))


def settle_generated_code() -> None:
    """Write what was compiled anew, give the modules their builtins back
    and let the cache go (what is created from now on compiles as usual)."""
    global _active
    cache, _active = _active, None
    if cache is None:
        return
    while _stood_in:
        module, name = _stood_in.pop()
        module.__dict__.pop(name, None)
    cache.save()


__all__ = ["MAX_ENTRIES", "cache_generated_code", "cache_path", "settle_generated_code"]
