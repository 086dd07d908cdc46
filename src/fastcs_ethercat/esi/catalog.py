"""The catalog: which terminal types and revisions a set of ESI files holds.

`build_catalog` lists every device cheaply (identity, names, group type,
whether it has PDO groups, file and line) and caches the rows by file content
(see `cache`); `load_device` then fully parses one device, `parse_all` every
device.

Every row is also parsed in full once (cached with the row), so the catalog
knows which devices do not parse: old generic catalogues (`Beckhoff EtherCAT
Terminals.xml`) describe placeholder revisions such as #x270b0000 whose PDOs
are only references (`<TxPdo Ref=... Chn=...>`, no `<Index>`).

Revisions: `find(type)` gives the newest *usable* revision, `find(type, rev)`
an exact one, `revisions(type)` all of them (`problem` says which do not
parse). Usable means: it parses, and no parsing revision of the same product
hides it with a `HideType` (Beckhoff's files hide superseded revisions and
the catalogue placeholders #x27070000, #x27080000, #x270b0000 that way, as
TwinCAT's own catalogue does). When the same type and revision appear in
several files (EL3602 #x00100000 is in both EL3xxx.xml copies), a copy that
parses wins, then the copy from the file holding the newest revision of that
type (the more recent download); ties go to the first file in sorted order.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lxml import etree

from fastcs_ethercat.bounded import esi_limit, read_bytes_bounded
from fastcs_ethercat.collector import held
from fastcs_ethercat.errors import UserError

from .cache import CatalogCache, sha256_of
from .device import describe, identity_of, name_of, parse_device
from .files import (
    EsiFileResult,
    device_elements,
    device_error,
    device_label,
    identity_or_none,
    parse_device_element,
    parse_document,
    placed,
    read_root,
    vendor_id_of,
)
from .groups import has_alternatives
from .memo import ParseMemo
from .model import CatalogEntry, EsiDevice, parse_esi_int
from .sources import EsiDocument, SourceArg, find_documents
from .xmltext import Element, EsiFormatError, fail, text_of

_Row = list[Any]
"""Cached form of a CatalogEntry (its fields in order, no source): see `_row`
/ `_entry`."""
_Scan = tuple[list[_Row], list[str], list[str]]
"""Rows, warnings and passive device names of one document."""


def _row(
    device: Element, position: int, vendor_id: int, name: str, memo: ParseMemo
) -> _Row | None:
    identity = identity_or_none(device)
    if identity is None:
        return None
    type_name, product_code, revision = identity
    names: dict[int, str] = {}
    group_type = ""
    hides: list[int] = []
    for child in device:
        if child.tag == "Name":
            name_of(child, names)
        elif child.tag == "GroupType":
            group_type = text_of(child)
        elif child.tag == "HideType":
            hidden = _hidden_revision(child, product_code)
            if hidden is not None and hidden != revision:
                hides.append(hidden)
    return [
        type_name,
        revision,
        product_code,
        vendor_id,
        group_type,
        has_alternatives(device),
        describe(names, type_name),
        device.sourceline or 0,
        position,
        _problem(device, vendor_id, name, memo),
        hides,
    ]


def _hidden_revision(element: Element, product_code: int) -> int | None:
    """The revision a `HideType` hides, if it is one of this product's."""
    try:
        code = element.get("ProductCode")
        if code is not None and parse_esi_int(code) != product_code:
            return None
        revision = element.get("RevisionNo")
        return parse_esi_int(revision) if revision is not None else None
    except ValueError:
        return None


def _problem(device: Element, vendor_id: int, name: str, memo: ParseMemo) -> str:
    """Why the device does not parse in full ("" when it does)."""
    try:
        parse_device(device, vendor_id=vendor_id, source=name, memo=memo)
    except EsiFormatError as error:
        line = error.line or device.sourceline or 0
        return f"line {line}: {error.message}"
    except RecursionError:
        return f"line {device.sourceline or 0}: nesting too deep"
    return ""


def _entry(row: _Row, source: str) -> CatalogEntry:
    """The entry of a row: the row holds its fields in order (`described`:
    type name to description), without `source`, with "" for no problem and
    a list for the hidden revisions."""
    *described, line, position, problem, hides = row
    return CatalogEntry(
        *described,
        source=source,
        line=line,
        device_position=position,
        problem=problem or None,
        hides=tuple(hides),
    )


@held()  # a burst that only builds objects: see `collector`
def scan_document(data: bytes, name: str) -> _Scan:
    """Catalog rows, one-line warnings and passive devices of one document
    (never raises)."""
    try:
        root = read_root(data, name)
        vendor_id = vendor_id_of(root, name)
    except UserError as error:
        return [], [str(error)], []
    rows: list[_Row] = []
    warnings: list[str] = []
    passive: list[str] = []
    memo = ParseMemo()
    copies = _Copies(name)
    for position, device in enumerate(device_elements(root)):
        try:
            row = _row(device, position, vendor_id, name, memo)
            if row is None:
                passive_name = _passive_name(device)
                if passive_name:
                    passive.append(passive_name)
                    continue
                identity_of(device)  # raises what is wrong with the <Type>
                raise fail(device, "<Type> lacks a name or ProductCode")
        except EsiFormatError as error:
            warnings.append(str(device_error(error, device, position, name)))
            continue
        rows.append(row)
        copies.check(device, position, row, warnings)
    return rows, warnings, passive


class _Copies:
    """A type and revision described twice in one document: the same text
    again is harmless, a different one is reported (which copy TwinCAT
    takes is not said anywhere)."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._first: dict[tuple[str, int], Element] = {}

    def check(
        self, device: Element, position: int, row: _Row, warnings: list[str]
    ) -> None:
        key = (row[0], row[1])
        first = self._first.setdefault(key, device)
        if first is device or _text(first) == _text(device):
            return
        message = (
            f"{device_label(device, position)}: a second, different copy "
            f"(the first is at line {first.sourceline})"
        )
        warnings.append(str(placed(message, self._name, device)))


def _text(device: Element) -> bytes:
    return etree.tostring(device, with_tail=False)


def _passive_name(device: Element) -> str | None:
    """The type name of a passive terminal (end caps, potential feeds, EL9xxx):
    no product code and no process data, so it never shows up on the bus.
    A device with process data but no product code is a broken one."""
    type_element = device.find("Type")
    if type_element is None or type_element.get("ProductCode") is not None:
        return None
    if any(child.tag in ("TxPdo", "RxPdo", "Sm") for child in device):
        return None
    return text_of(type_element) or None


class EsiCatalog:
    """Devices (type + revision) of a set of ESI documents, for listing."""

    def __init__(
        self,
        entries: Iterable[CatalogEntry],
        warnings: Iterable[str] = (),
        documents: Iterable[EsiDocument] = (),
        passive: Iterable[str] = (),
    ) -> None:
        self.entries: tuple[CatalogEntry, ...] = tuple(entries)
        self.warnings: tuple[str, ...] = tuple(warnings)
        self.passive: tuple[str, ...] = tuple(sorted(set(passive)))
        """Devices without a product code (passive terminals), by type."""
        self._documents = {document.name: document for document in documents}
        self._roots: OrderedDict[str, Element] = OrderedDict()
        by_type: dict[str, list[CatalogEntry]] = {}
        for entry in self.entries:
            by_type.setdefault(entry.type_name, []).append(entry)
        self._by_type = {name: _preferred(found) for name, found in by_type.items()}
        self._folded = {name.casefold(): name for name in self._by_type}

    def __len__(self) -> int:
        return len(self.entries)

    def type_names(self) -> list[str]:
        """Every terminal type, sorted."""
        return sorted(self._by_type)

    def _type(self, type_name: str) -> str:
        if type_name in self._by_type:
            return type_name
        folded = self._folded.get(type_name.casefold())
        if folded is None:
            raise UserError(
                f"no ESI description of terminal type {type_name!r} "
                f"among {len(self.entries)} devices",
                where=type_name,
            )
        return folded

    def revisions(self, type_name: str) -> tuple[CatalogEntry, ...]:
        """One entry per revision of a type, oldest first (broken ones too)."""
        return self._by_type[self._type(type_name)]

    def usable(self, type_name: str) -> tuple[CatalogEntry, ...]:
        """Revisions that parse and that no parsing revision hides, oldest first."""
        return usable_revisions(self.revisions(type_name))

    def newest_usable(self, type_name: str) -> CatalogEntry | None:
        """The revision `find(type)` chooses; None when no revision parses.

        Without a usable one, the newest that parses (every parsing revision
        hidden would be a strange file, but still better than nothing)."""
        found = self.revisions(type_name)
        usable = usable_revisions(found)
        if usable:
            return usable[-1]
        parsing = [entry for entry in found if entry.parses]
        return parsing[-1] if parsing else None

    def find(self, type_name: str, revision: int | None = None) -> CatalogEntry:
        """Newest usable revision of a type, or exactly `revision`."""
        found = self.revisions(type_name)
        if revision is None:
            chosen = self.newest_usable(type_name)
            if chosen is None:
                reasons = "; ".join(
                    f"#x{entry.revision:08x} {entry.problem}" for entry in found
                )
                raise UserError(
                    f"no revision of {found[0].type_name} parses ({reasons})",
                    path=found[-1].source,
                    where=str(found[-1].line),
                )
            return chosen
        for entry in found:
            if entry.revision == revision:
                return entry
        known = ", ".join(f"#x{entry.revision:08x}" for entry in found)
        raise UserError(
            f"{found[0].type_name} has no revision #x{revision:08x} (known: {known})",
            where=found[0].type_name,
        )

    def newest(self) -> tuple[CatalogEntry, ...]:
        """Per type, sorted by name: what `find(type)` chooses, or the newest
        revision when none parses (its `problem` says why)."""
        return tuple(
            self.newest_usable(name) or self._by_type[name][-1]
            for name in self.type_names()
        )

    def _root(self, source: str) -> Element:
        """Parsed document, keeping the last two (a device is often followed
        by its siblings from the same file)."""
        if source in self._roots:
            self._roots.move_to_end(source)
            return self._roots[source]
        document = self._documents.get(source) or EsiDocument(
            name=source, container=Path(source)
        )
        root = read_root(document.read(), source)
        self._roots[source] = root
        while len(self._roots) > 2:
            self._roots.popitem(last=False)
        return root

    def load(self, type_name: str, revision: int | None = None) -> EsiDevice:
        """Fully parse one device (newest revision unless `revision` given)."""
        entry = self.find(type_name, revision)
        root = self._root(entry.source)
        devices = device_elements(root)
        position = entry.device_position
        if not (position < len(devices) and _matches(devices[position], entry)):
            position = next(
                (i for i, device in enumerate(devices) if _matches(device, entry)), -1
            )
            if position < 0:
                raise UserError(
                    f"device {entry.type_name} revision #x{entry.revision:08x} "
                    "is no longer in the file (rebuild the catalog)",
                    path=entry.source,
                    where=str(entry.line),
                )
        return parse_device_element(
            devices[position],
            position,
            vendor_id=vendor_id_of(root, entry.source),
            source=entry.source,
        )


def _matches(device: Element, entry: CatalogEntry) -> bool:
    identity = identity_or_none(device)
    return (
        identity is not None
        and identity[0] == entry.type_name
        and (identity[2] == entry.revision)
    )


def usable_revisions(entries: Iterable[CatalogEntry]) -> tuple[CatalogEntry, ...]:
    """Entries that parse and that no parsing entry hides (see module doc)."""
    parsing = [entry for entry in entries if entry.parses]
    hidden = {revision for entry in parsing for revision in entry.hides}
    return tuple(entry for entry in parsing if entry.revision not in hidden)


def _preferred(entries: list[CatalogEntry]) -> tuple[CatalogEntry, ...]:
    """One entry per revision (see the module docstring), oldest first."""
    newest_in_file: dict[str, int] = {}
    for entry in entries:
        newest_in_file[entry.source] = max(
            newest_in_file.get(entry.source, entry.revision), entry.revision
        )
    chosen: dict[int, CatalogEntry] = {}
    for entry in entries:
        current = chosen.get(entry.revision)
        if current is None or (entry.parses, newest_in_file[entry.source]) > (
            current.parses,
            newest_in_file[current.source],
        ):
            chosen[entry.revision] = entry
    return tuple(chosen[revision] for revision in sorted(chosen))


_ROW_TYPES = (str, int, int, int, str, bool, str, int, int, str, list)


def _valid_row(row: object) -> bool:
    """A cached row has the shape `_row` writes (else the cache is stale)."""
    return (
        isinstance(row, list)
        and len(row) == len(_ROW_TYPES)
        and all(isinstance(v, t) for v, t in zip(row, _ROW_TYPES, strict=True))
        and all(isinstance(v, int) for v in row[-1])
    )


def _from_cache(
    cache: CatalogCache, sha: str, documents: list[EsiDocument]
) -> dict[str, _Scan] | None:
    cached = cache.load(sha)
    if cached is None:
        return None
    results: dict[str, _Scan] = {}
    for document in documents:
        value = cached.get(document.member or "")
        if not (isinstance(value, list) and len(value) == 3):
            return None
        rows, warnings, passive = value
        if not (
            isinstance(rows, list)
            and isinstance(warnings, list)
            and isinstance(passive, list)
            and all(_valid_row(row) for row in rows)
            and all(isinstance(text, str) for text in (*warnings, *passive))
        ):
            return None
        results[document.name] = (rows, warnings, passive)
    return results


def _scan_container(
    container: Path, documents: list[EsiDocument], cache: CatalogCache | None
) -> dict[str, _Scan]:
    """Rows per document of one file on disk, through the cache if given."""
    if cache is not None:
        sha = cache.known_sha(container)
        if sha is not None:
            cached = _from_cache(cache, sha, documents)
            if cached is not None:
                return cached
    try:
        data = read_bytes_bounded(container, esi_limit(container), what="ESI file")
    except UserError as error:
        return {d.name: ([], [str(error)], []) for d in documents}
    sha = sha256_of(data)
    if cache is not None:
        cached = _from_cache(cache, sha, documents)
        if cached is not None:
            cache.remember(container, sha)
            return cached
    results: dict[str, _Scan] = {}
    for document in documents:
        try:
            content = document.read_from(data)
        except UserError as error:
            results[document.name] = ([], [str(error)], [])
        else:
            results[document.name] = scan_document(content, document.name)
    if cache is not None:
        cache.store(sha, {(d.member or ""): list(results[d.name]) for d in documents})
        cache.remember(container, sha)
    return results


def build_catalog(
    source: SourceArg, *, use_cache: bool = True, cache_dir: Path | None = None
) -> EsiCatalog:
    """List every device of the ESI documents under `source`.

    `source`: a directory (searched recursively for *.xml and *.zip), a file,
    a `Beckhoff_EtherCAT_XML.zip`, or a list of those. Unreadable documents
    and broken devices become `warnings` (one line each, naming file, line
    and device); the rest is listed.
    """
    documents = find_documents(source)
    cache = CatalogCache(cache_dir) if use_cache else None
    by_container: dict[Path, list[EsiDocument]] = {}
    for document in documents:
        by_container.setdefault(document.container, []).append(document)
    entries: list[CatalogEntry] = []
    warnings: list[str] = []
    passive: list[str] = []
    for container, members in by_container.items():
        scanned = _scan_container(container, members, cache)
        for document in members:
            rows, found, passive_here = scanned[document.name]
            entries.extend(_entry(row, document.name) for row in rows)
            warnings.extend(found)
            passive.extend(passive_here)
    if cache is not None:
        cache.flush()
    return EsiCatalog(entries, warnings, documents, passive)


def load_device(
    catalog: EsiCatalog, type_name: str, revision: int | None = None
) -> EsiDevice:
    """Fully parse one device of a catalog (newest revision by default)."""
    return catalog.load(type_name, revision)


@dataclass(frozen=True, slots=True)
class EsiParseResult:
    """Every device of a set of documents, and what could not be parsed."""

    devices: tuple[EsiDevice, ...]
    warnings: tuple[UserError, ...]
    files: tuple[EsiFileResult, ...]


@held()  # one burst for every document: see `collector`
def parse_all(source: SourceArg, *, strict: bool = False) -> EsiParseResult:
    """Fully parse every device under `source` (see `build_catalog`).

    Non-strict: unreadable documents and broken devices become warnings.
    Strict: the first one is raised.
    """
    devices: list[EsiDevice] = []
    warnings: list[UserError] = []
    files: list[EsiFileResult] = []
    memo = ParseMemo()
    for document in find_documents(source):
        try:
            data = document.read()
            result = parse_document(data, document.name, strict=strict, memo=memo)
        except UserError as error:
            if strict:
                raise
            warnings.append(error)
            continue
        files.append(result)
        devices.extend(result.devices)
        warnings.extend(result.warnings)
    return EsiParseResult(tuple(devices), tuple(warnings), tuple(files))


__all__ = [
    "EsiCatalog",
    "EsiParseResult",
    "build_catalog",
    "load_device",
    "parse_all",
    "scan_document",
    "usable_revisions",
]
