"""Read what users give us within bounds: file sizes, YAML aliases and depth.

Every file the project reads (ESI XML, IOC config, chain files, terminal YAML,
ACF, catio files) comes through here, so a path naming an endless device
(/dev/zero, a FIFO fed forever), a 1 GB file or a YAML alias bomb fails in
one line naming the file, in bounded time and memory, instead of reading
until memory runs out.
"""

from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, get_args

from fastcs_ethercat.errors import UserError

if TYPE_CHECKING:
    from pydantic import BaseModel, ValidationInfo

MIB: Final = 1024 * 1024
MAX_ESI_BYTES: Final = 16 * MIB
"""One ESI document: 4x Beckhoff's largest (ELM37xx.xml, 3.9 MB). Parsing
takes about 12x a document's size in memory (a 38 MB one took 470 MB), so
this keeps a parse near 200 MB."""
MAX_ESI_ZIP_BYTES: Final = 512 * MIB
"""A zip of ESI documents (Beckhoff's whole set is under 100 MB packed)."""
MAX_TERMINAL_YAML_BYTES: Final = 8 * MIB
"""One terminal YAML file (the largest shipped, ELM3704-0000, is 0.7 MB)."""
MAX_CHAIN_BYTES: Final = 16 * MIB
"""One chain file (a dump of a 100-terminal rack with its CoE is ~1 MB)."""
MAX_CONFIG_BYTES: Final = 4 * MIB
"""An IOC configuration file."""
MAX_ACF_BYTES: Final = 1 * MIB
"""An EPICS access security file."""
MAX_CATIO_BYTES: Final = 64 * MIB
"""A catio-terminals `terminal_types.yaml` (every type in one file)."""
MAX_YAML_ALIAS_NODES: Final = 10_000
"""Nodes YAML aliases may add beyond the document's own: a few anchors are
fine, 9 levels of 9 (a billion nodes from a few hundred bytes) are not."""
MAX_YAML_DEPTH: Final = 64
"""Nesting of YAML mappings and lists (our files nest fewer than 10 deep)."""


def _size_text(limit: int) -> str:
    return f"{limit // MIB} MiB" if limit >= MIB else f"{limit // 1024} KiB"


def _label(what: str) -> str:
    return f"{what}: " if what else ""


def _too_large(what: str, limit: int, path: Path | str, where: str | None) -> UserError:
    return UserError(
        f"{_label(what)}larger than {_size_text(limit)}: refused",
        path=path,
        where=where,
    )


def read_bytes_bounded(
    path: Path | str, limit: int, *, what: str = "", where: str | None = None
) -> bytes:
    """The bytes of `path`, at most `limit` of them; `UserError` (naming the
    file and `what` it is) when unreadable or larger. A regular file's size
    is known before reading; anything else (a device, a FIFO) is read up to
    `limit + 1` bytes and no further."""
    try:
        with open(path, "rb") as stream:
            info = os.fstat(stream.fileno())
            if stat.S_ISREG(info.st_mode) and info.st_size > limit:
                raise _too_large(what, limit, path, where)
            data = stream.read(limit + 1)
    except FileNotFoundError:
        raise UserError(f"no such {what or 'file'}", path=path, where=where) from None
    except OSError as error:
        reason = error.strerror or str(error)
        target = f" {what}" if what else ""
        raise UserError(
            f"cannot read{target}: {reason}", path=path, where=where
        ) from None
    if len(data) > limit:
        raise _too_large(what, limit, path, where)
    return data


def read_text_bounded(
    path: Path | str, limit: int, *, what: str = "", where: str | None = None
) -> str:
    """The UTF-8 text of `path` (see `read_bytes_bounded`); bytes that are not
    UTF-8 are one line naming the offset."""
    data = read_bytes_bounded(path, limit, what=what, where=where)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise UserError(
            f"{_label(what)}not UTF-8 text (byte 0x{data[error.start]:02x} at "
            f"offset {error.start})",
            path=path,
            where=where,
        ) from None


def esi_limit(path: Path | str) -> int:
    """The bound of an ESI file on disk: a zip holds many documents."""
    return MAX_ESI_ZIP_BYTES if str(path).lower().endswith(".zip") else MAX_ESI_BYTES


def read_member_bounded(
    archive: zipfile.ZipFile, member: str, limit: int, *, name: str
) -> bytes:
    """One zip member's bytes, at most `limit` (a zip bomb's member says how
    large it unpacks; the read stops at the bound whatever it says)."""
    info = archive.getinfo(member)
    if info.file_size > limit:
        raise _too_large("ESI document", limit, name, None)
    with archive.open(info) as stream:
        data = stream.read(limit + 1)
    if len(data) > limit:
        raise _too_large("ESI document", limit, name, None)
    return data


class YamlBudget:
    """Counts the nodes a YAML document builds: aliases may add at most
    `MAX_YAML_ALIAS_NODES` beyond the document's own nodes, and nothing may
    nest deeper than `MAX_YAML_DEPTH` (see `terminals.yaml_io`)."""

    def __init__(self) -> None:
        self._seen: set[int] = set()
        self._built = 0

    def problem(self, node: object, depth: int) -> str | None:
        """Why building `node` at `depth` would exceed a bound (None: fine)."""
        if depth > MAX_YAML_DEPTH:
            return f"nested deeper than {MAX_YAML_DEPTH} levels"
        self._built += 1
        self._seen.add(id(node))
        if self._built - len(self._seen) > MAX_YAML_ALIAS_NODES:
            return f"aliases expand to more than {MAX_YAML_ALIAS_NODES} extra nodes"
        return None


MAX_MAGNITUDE: Final = 2**64
"""Numbers in a file lie within +-2**64 (no field of ours holds more; a
5 000-digit integer is a mistake, not a value)."""


def number_problem(value: object) -> str | None:
    """Why a number read from a file is refused (None: fine)."""
    if isinstance(value, int) and not -MAX_MAGNITUDE <= value < MAX_MAGNITUDE:
        return "number out of range (beyond +-2**64)"
    return None


def _numeric(annotation: object) -> bool:
    if annotation in (int, float):
        return True
    return any(_numeric(arg) for arg in get_args(annotation) if arg is not bool)


def no_bool_for_number(cls: type[BaseModel], value: Any, info: ValidationInfo) -> Any:
    """`value`, unless it is a YAML boolean given for a number field (pydantic
    takes `true` as 1): call from a model's `field_validator("*", mode="before")`."""
    if value.__class__ is bool and info.field_name is not None:
        field = cls.model_fields.get(info.field_name)
        if field is not None and _numeric(field.annotation):
            raise ValueError(f"a number is wanted, not {str(value).lower()}")
    return value
