"""Where ESI documents come from: a directory tree, single files, or the
`Beckhoff_EtherCAT_XML.zip` Beckhoff distributes.

A document is named `path` for a file and `zip!member` for a zip member; that
name is what error messages and `EsiDevice.source` show.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fastcs_ethercat.bounded import (
    MAX_ESI_BYTES,
    read_bytes_bounded,
    read_member_bounded,
)
from fastcs_ethercat.errors import UserError

ZIP_SEPARATOR = "!"

SourceArg = Path | str | Sequence[Path | str]


@dataclass(frozen=True, slots=True)
class EsiDocument:
    """One XML document: a file on disk or a member of a zip archive."""

    name: str
    """`path` or `zip!member`, as shown to users."""
    container: Path
    """The file on disk holding it (the zip for a member)."""
    member: str | None = None

    def read_from(self, container_bytes: bytes) -> bytes:
        """The document's bytes, given the bytes of its container file."""
        if self.member is None:
            return container_bytes
        try:
            with zipfile.ZipFile(io.BytesIO(container_bytes)) as archive:
                return read_member_bounded(
                    archive, self.member, MAX_ESI_BYTES, name=self.name
                )
        except (KeyError, zipfile.BadZipFile) as error:
            raise UserError(
                f"cannot read ESI document: {error}", path=self.name
            ) from None

    def read(self) -> bytes:
        """The raw bytes (encoding is left to the XML declaration)."""
        if self.member is None:
            return read_bytes_bounded(self.container, MAX_ESI_BYTES, what="ESI file")
        try:
            with zipfile.ZipFile(self.container) as archive:
                return read_member_bounded(
                    archive, self.member, MAX_ESI_BYTES, name=self.name
                )
        except (OSError, KeyError, zipfile.BadZipFile) as error:
            raise UserError(
                f"cannot read ESI document: {error}", path=self.name
            ) from None


def _as_paths(source: SourceArg) -> list[Path]:
    if isinstance(source, str | Path):
        return [Path(source)]
    return [Path(item) for item in source]


def _zip_documents(path: Path) -> list[EsiDocument]:
    try:
        with zipfile.ZipFile(path) as archive:
            members = sorted(
                info.filename
                for info in archive.infolist()
                if not info.is_dir() and info.filename.lower().endswith(".xml")
            )
    except (OSError, zipfile.BadZipFile) as error:
        raise UserError(
            f"not a readable zip archive: {error}", path=str(path)
        ) from None
    return [
        EsiDocument(
            name=f"{path}{ZIP_SEPARATOR}{member}", container=path, member=member
        )
        for member in members
    ]


def _is_xml(path: Path) -> bool:
    return path.suffix.lower() == ".xml"


def find_documents(source: SourceArg) -> list[EsiDocument]:
    """Every ESI document under the given directories, files and zips.

    Directories are searched recursively for `*.xml` and `*.zip` (sorted, so
    the order is stable); a missing path is a `UserError`.
    """
    documents: list[EsiDocument] = []
    for path in _as_paths(source):
        if path.is_dir():
            for found in sorted(_walk(path)):
                documents.extend(_documents_of(found))
        elif path.is_file():
            documents.extend(_documents_of(path))
        else:
            raise UserError("no such ESI file or directory", path=str(path))
    return documents


def _walk(directory: Path) -> Iterable[Path]:
    for path in directory.rglob("*"):
        if path.is_file() and (_is_xml(path) or path.suffix.lower() == ".zip"):
            yield path


def _documents_of(path: Path) -> list[EsiDocument]:
    if path.suffix.lower() == ".zip":
        return _zip_documents(path)
    return [EsiDocument(name=str(path), container=path)]
