"""The audit of puts: every put a client makes through the EPICS database,
logged once with who made it.

EPICS's asTrapWrite (what caPutLog uses) calls its listeners for each put
that an access security rule marked TRAPWRITE; the CA server and QSRV (PV
Access served from the database) both go through it. softioc's documented
`softioc.pvlog` registers such a listener, which prints one line a put on
the IOC's stdout (the container log):

    operator@bl01-opi-01 BL01T-EA-ECAT-01:ETH1:RIO18:MOD20:CH1:Output.VAL 0 -> 1

and loads an ACF whose every WRITE is TRAPWRITE. A site's ACF (or the
read-only one) is loaded in its place: `trapwrite_acf` adds TRAPWRITE to its
WRITE rules, so its puts are audited too.
"""

from __future__ import annotations

import ctypes
import re
from pathlib import Path
from typing import Final

_WRITE_RULE: Final = re.compile(r"\bRULE\(\s*(\d+)\s*,\s*WRITE\s*\)")
"""A WRITE rule that says nothing of TRAPWRITE (NOTRAPWRITE is kept)."""
AUDITED_ACF: Final = "audited.acf"
_IOLBF: Final = 1
"""glibc's `_IOLBF` (line buffered), for `setvbuf`."""


def install_put_audit() -> None:
    """Log every put from now on; call before iocInit (and before a site's
    ACF is loaded, which then replaces softioc's)."""
    _line_buffered_c_stdout()
    import softioc.pvlog  # noqa: F401  (importing it installs the listener)


def _line_buffered_c_stdout() -> None:
    """C's stdout a line at a time (libc `setvbuf`): the put lines are
    printed by C, and on a pipe (a container without a tty, a log shipper)
    C would hold them until 4 KiB have gathered."""
    libc = ctypes.CDLL(None)
    stdout = ctypes.c_void_p.in_dll(libc, "stdout")
    libc.setvbuf.argtypes = (
        ctypes.c_void_p,
        ctypes.c_char_p,
        ctypes.c_int,
        ctypes.c_size_t,
    )
    libc.setvbuf(stdout, None, _IOLBF, 0)


def trapwrite_text(text: str) -> str:
    """`text` (an ACF) with TRAPWRITE on each WRITE rule that has no option."""
    return _WRITE_RULE.sub(r"RULE(\1, WRITE, TRAPWRITE)", text)


def trapwrite_acf(acf: Path, directory: Path) -> Path:
    """`acf` as `trapwrite_text` makes it, written into `directory`."""
    path = directory / AUDITED_ACF
    path.write_text(trapwrite_text(acf.read_text(encoding="utf-8")), encoding="utf-8")
    return path


__all__ = ["install_put_audit", "trapwrite_acf", "trapwrite_text"]
