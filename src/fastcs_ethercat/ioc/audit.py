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
WRITE rules, so its puts are audited too. For a PV Access put the host is
the client's IP address: QSRV gives asTrapWrite the peer's address, where
the CA server gives the host name the client sent.

The listener prints each line in pieces (a printf per word): C's stdout is
given a line buffer of its own, so no other output lands inside a line, and
FastCS's own line of each put (`PV put: X = v` at INFO, without the client)
is left to DEBUG, so at INFO a put is one line.
"""

from __future__ import annotations

import ctypes
import logging
import re
from pathlib import Path
from typing import Final

_WRITE_RULE: Final = re.compile(r"\bRULE\(\s*(\d+)\s*,\s*WRITE\s*\)")
"""A WRITE rule that says nothing of TRAPWRITE (NOTRAPWRITE is kept)."""
AUDITED_ACF: Final = "audited.acf"
_IOLBF: Final = 1
"""glibc's `_IOLBF` (line buffered), for `setvbuf`."""
LINE_BUFFER_BYTES: Final = 8192
"""C stdout's line buffer: longer than any put line (an array's is cut
by softioc's listener to a few hundred bytes)."""
FASTCS_PUT_LOGGER: Final = "fastcs.transports.epics.ca.ioc"
"""The FastCS module that logs each put to a record at INFO (`PV put`)."""


def install_put_audit() -> None:
    """Log every put from now on; call before iocInit (and before a site's
    ACF is loaded, which then replaces softioc's)."""
    _line_buffered_c_stdout()
    import softioc.pvlog  # noqa: F401  (importing it installs the listener)

    if not logging.getLogger().isEnabledFor(logging.DEBUG):
        logging.getLogger(FASTCS_PUT_LOGGER).setLevel(logging.WARNING)


def _line_buffered_c_stdout() -> None:
    """C's stdout a line at a time (libc `setvbuf`), in a buffer of its own.

    On a pipe (a container without a tty, a log shipper) C would hold the
    put lines until 4 KiB have gathered. Under PYTHONUNBUFFERED (as in the
    image) Python has made C's stdout unbuffered, with a 1-byte buffer that
    line buffering without a buffer of its own would keep: every printf
    would be written on its own, and a put line split by other output. The
    buffer is malloc'd and never freed: C writes into it until exit.
    """
    libc = ctypes.CDLL(None)
    stdout = ctypes.c_void_p.in_dll(libc, "stdout")
    libc.malloc.argtypes = (ctypes.c_size_t,)
    libc.malloc.restype = ctypes.c_void_p
    libc.setvbuf.argtypes = (
        ctypes.c_void_p,
        ctypes.c_void_p,
        ctypes.c_int,
        ctypes.c_size_t,
    )
    libc.fflush(stdout)
    buffer = libc.malloc(LINE_BUFFER_BYTES)
    libc.setvbuf(stdout, buffer, _IOLBF, LINE_BUFFER_BYTES if buffer else 0)


def trapwrite_text(text: str) -> str:
    """`text` (an ACF) with TRAPWRITE on each WRITE rule that has no option."""
    return _WRITE_RULE.sub(r"RULE(\1, WRITE, TRAPWRITE)", text)


def trapwrite_acf(acf: Path, directory: Path) -> Path:
    """`acf` as `trapwrite_text` makes it, written into `directory`."""
    path = directory / AUDITED_ACF
    path.write_text(trapwrite_text(acf.read_text(encoding="utf-8")), encoding="utf-8")
    return path


__all__ = ["install_put_audit", "trapwrite_acf", "trapwrite_text"]
