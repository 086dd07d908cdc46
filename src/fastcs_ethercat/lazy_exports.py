"""Package re-exports imported when first used (a module `__getattr__`).

A package `__init__` that imports every public name eagerly makes each user
of one submodule pay for all of them: the IOC, which loads terminal YAML,
would import the ESI parser through `terminals/__init__`.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping


def lazy_exports(package: str, exports: Mapping[str, str]) -> Callable[[str], object]:
    """The `__getattr__` of `package`: `exports` maps each public name to
    the submodule it lives in; found once, the name is kept in the package."""

    def __getattr__(name: str) -> object:
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{exports[name]}"), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__
