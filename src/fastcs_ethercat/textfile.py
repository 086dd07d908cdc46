"""Read a user's text file whole, but never more than a bound.

A config path that names an endless device (/dev/zero, a FIFO fed forever)
must fail in one line instead of reading until memory runs out; bytes that
are not UTF-8 are one line naming the offset, not a traceback.
"""

from __future__ import annotations

from pathlib import Path

from fastcs_ethercat.errors import UserError


def read_text_bounded(
    path: Path,
    limit: int,
    *,
    what: str = "",
    where: str | None = None,
) -> str:
    """The UTF-8 text of `path`; `UserError` if unreadable, larger than
    `limit` bytes or not UTF-8 (`what` names the file in the message)."""
    label = f"{what}: " if what else ""
    try:
        with path.open("rb") as stream:
            data = stream.read(limit + 1)
    except OSError as error:
        reason = error.strerror or str(error)
        target = f" {what}" if what else ""
        raise UserError(
            f"cannot read{target}: {reason}", path=path, where=where
        ) from None
    if len(data) > limit:
        raise UserError(
            f"{label}larger than {limit // 1024} KiB: not a configuration file",
            path=path,
            where=where,
        )
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise UserError(
            f"{label}not UTF-8 text (byte 0x{data[error.start]:02x} at offset "
            f"{error.start})",
            path=path,
            where=where,
        ) from None
