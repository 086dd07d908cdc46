"""Which ESI revision a terminal file is (re)generated from.

A file belongs to a revision lineage: its product code, its variant (the low
16 bits of the revision: `-0010` is 10) and the ESI file it came from
(`esi_file`). Regenerating moves it to the newest usable revision of that
lineage and never anywhere else on its own: not to a revision of another
variant, not to another file's description of the type (an old generic
catalogue's placeholder #x270b0000 would leave a live terminal without a
matching YAML), and never back to an older revision. Moving elsewhere takes
an explicit `--revision`.
"""

from __future__ import annotations

from dataclasses import dataclass

from fastcs_ethercat.esi.catalog import EsiCatalog, usable_revisions
from fastcs_ethercat.esi.model import CatalogEntry
from fastcs_ethercat.terminals.generate import esi_file_name
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.registry import variant_of


@dataclass(frozen=True)
class RevisionChoice:
    """The revision to regenerate from, or why the file stays as it is."""

    entry: CatalogEntry | None
    note: str | None = None
    """Why the file stays unchanged, or what was passed over."""


def _in_lineage(entry: CatalogEntry, terminal: TerminalType) -> bool:
    identity = terminal.identity
    return (
        entry.product_code == identity.product_code
        and variant_of(entry.revision) == variant_of(identity.revision_number)
        and (
            terminal.esi_file is None
            or esi_file_name(entry.source) == terminal.esi_file
        )
    )


def regenerate_revision(
    catalog: EsiCatalog,
    type_name: str,
    terminal: TerminalType,
    *,
    requested: int | None = None,
    keep_revision: bool = False,
) -> RevisionChoice:
    """The catalog entry `type_name`'s file should be regenerated from."""
    current = terminal.identity.revision_number
    if requested is not None:
        return RevisionChoice(catalog.find(type_name, requested))
    found = catalog.revisions(type_name)
    if keep_revision:
        same = [e for e in found if e.revision == current and e.parses]
        if same:
            return RevisionChoice(same[0])
        return RevisionChoice(None, f"revision #x{current:08x} is not in the ESI files")
    usable = set(usable_revisions(found))
    candidates = [
        e
        for e in found
        if _in_lineage(e, terminal)
        and e.revision >= current
        and (e in usable or (e.revision == current and e.parses))
    ]
    passed_over = _passed_over(catalog, type_name, terminal)
    if candidates:
        return RevisionChoice(candidates[-1], passed_over)
    where = terminal.esi_file or "the ESI files"
    product = terminal.identity.product_code
    return RevisionChoice(
        None,
        f"no usable revision of its lineage (product 0x{product:08x}, "
        f"variant {variant_of(current)}, {where}) at or after #x{current:08x}"
        + (f"; {passed_over}" if passed_over else ""),
    )


def _passed_over(
    catalog: EsiCatalog, type_name: str, terminal: TerminalType
) -> str | None:
    """A note when the catalog's newest revision lies outside the lineage."""
    newest = catalog.newest_usable(type_name)
    if newest is None or _in_lineage(newest, terminal):
        return None
    return (
        f"newest usable #x{newest.revision:08x} ({esi_file_name(newest.source)}) is "
        "another lineage: `--revision "
        f"{type_name}=0x{newest.revision:08x}` moves it there"
    )
