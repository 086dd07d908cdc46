"""The package's bytecode, compiled before any start is timed.

pip compiles every module of a wheel when it installs it (the image does),
so an installed IOC never compiles its own source. A checkout (an editable
install) has no bytecode until Python writes it, and with
`PYTHONDONTWRITEBYTECODE` set it never does: each IOC start would compile
~100 modules again (~0.25 s of CPU at 104 terminals), a cost no installed
IOC has. The benchmark therefore compiles them first, as the install would.
"""

from __future__ import annotations

import compileall
from pathlib import Path

import fastcs_ethercat


def compile_package() -> bool:
    """Write the missing or stale `__pycache__` files of the package; False
    if some could not be written (a read-only install: it has them)."""
    package = Path(fastcs_ethercat.__file__).parent
    return bool(compileall.compile_dir(package, quiet=2))
