"""Names from outside (an ESI `<Type>`, a catio file, a URL) before they
become file names: a terminal type name is letters, digits and `_.+-`,
starting with a letter or digit, so `../../x`, `/abs/x`, a separator or a
NUL never reach `directory / f"{name}.yaml"`; and a path built from one is
checked to stay in its directory."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Final

from fastcs_ethercat.errors import UserError

TYPE_NAME: Final = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}")
"""EL3104, EL3356-0010, ELM3704-0000 (every type in Beckhoff's files)."""


def is_type_name(name: object) -> bool:
    """Whether `name` may name a terminal type (and its file)."""
    return isinstance(name, str) and TYPE_NAME.fullmatch(name) is not None


def file_in(directory: Path, file_name: str) -> Path:
    """`directory / file_name`, refused (`UserError`) unless it is a plain
    name that stays in `directory` (no separator, no `..`, not absolute)."""
    plain = Path(file_name).name == file_name and file_name not in ("", ".", "..")
    if not plain or "\0" in file_name:
        raise UserError(f"{file_name[:80]!r} would be written outside {directory}")
    return directory / file_name
