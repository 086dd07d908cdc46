"""Import FastCS and the EPICS libraries without work an IOC never needs.

Two costs of IOC start that are not in our code but are paid in our process,
about a second together on a 2-core machine:

- `fastcs.transports` imports every transport it finds installed: REST
  (FastAPI), GraphQL and Tango as well as CA and PVA. It guards each with
  `except ImportError`, so refusing those three while FastCS is first imported
  just leaves them out; a later import of them works as usual.
- setuptools_dso (how epicscorelibs, pvxslibs and p4p find their shared
  libraries) learns its caller's package with `inspect.stack()`, which reads
  the source of every frame on the stack and scans `sys.modules` for each
  one. The caller two frames up is the frame `sys._getframe(2)` gives, and
  that frame's module name is in its globals.

Both only apply inside `lean_imports()`; outside it nothing is changed.
"""

from __future__ import annotations

import importlib
import importlib.abc
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Final

UNUSED_TRANSPORTS: Final = frozenset(
    {"fastcs.transports.rest", "fastcs.transports.graphql", "fastcs.transports.tango"}
)
"""FastCS transports an EtherCAT IOC never serves."""
IOC_MODULES: Final = (
    "fastcs",
    "fastcs.transports.epics.ca.transport",
    "fastcs.transports.epics.pva.transport",
)
"""What an IOC imports anyway: FastCS, softioc (CA) and p4p (PVA)."""


class _RefuseUnused(importlib.abc.MetaPathFinder):
    """Makes the unused transports look not installed."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> ModuleSpec | None:
        if fullname in UNUSED_TRANSPORTS:
            raise ModuleNotFoundError(f"{fullname} left out", name=fullname)
        return None


def _caller_package() -> str:
    """What setuptools_dso's `_auto_pkg` returns: the module name of the frame
    that called `find_dso`/`dylink_prepare_dso` (two frames up)."""
    return sys._getframe(2).f_globals["__name__"]  # pyright: ignore[reportPrivateUsage]


def _dso_runtime() -> ModuleType | None:
    try:
        return importlib.import_module("setuptools_dso.runtime")
    except ImportError:
        return None


@contextmanager
def lean_imports() -> Iterator[None]:
    """Within: unused FastCS transports are not imported, DSOs found quickly."""
    finder = _RefuseUnused()
    sys.meta_path.insert(0, finder)
    runtime = _dso_runtime()
    auto_pkg = getattr(runtime, "_auto_pkg", None)
    if runtime is not None and auto_pkg is not None:
        runtime._auto_pkg = _caller_package  # type: ignore[attr-defined]
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        if runtime is not None and auto_pkg is not None:
            runtime._auto_pkg = auto_pkg  # type: ignore[attr-defined]


def import_ioc_modules() -> None:
    """Import FastCS with its CA and PVA transports the quick way (once)."""
    if all(name in sys.modules for name in IOC_MODULES):
        return
    with lean_imports():
        for name in IOC_MODULES:
            importlib.import_module(name)
