"""What the editor edits: the terminal files of one directory, unsaved choices
in memory, the diff a save would make, and the ESI catalog to add types from.

No web code here: the pages only show this state and call these methods, and
every choice goes through `terminals.selection` and every save through
`terminals.saving`, exactly as the CLI's. Nothing is written before `save`.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.esi.model import CatalogEntry
from fastcs_ethercat.safe_names import file_in
from fastcs_ethercat.terminals.esi_sources import checkout_default_esi, open_catalog
from fastcs_ethercat.terminals.files import read_terminal_file, terminal_file_name
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.loader import terminal_paths
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.saving import (
    SavedFile,
    file_text,
    old_text,
    save_terminals,
)

SEARCH_LIMIT = 60


@dataclass
class EditedType:
    """One terminal type: as its file says, and as edited so far."""

    name: str
    path: Path
    saved: TerminalType | None
    """None for a type added from the catalog and not saved yet."""
    current: TerminalType

    @property
    def changed(self) -> bool:
        return self.current != self.saved

    @property
    def new(self) -> bool:
        """Added from the catalog; its file is written at the first save."""
        return self.saved is None

    def counts(self) -> tuple[int, int, int, int]:
        """(selected symbols, symbols, selected CoE objects, CoE objects)."""
        terminal = self.current
        return (
            sum(node.selected for node in terminal.symbol_nodes),
            len(terminal.symbol_nodes),
            sum(obj.selected for obj in terminal.coe_objects),
            len(terminal.coe_objects),
        )


class EditorSession:
    """The files of one directory and the catalog of the ESI sources."""

    def __init__(self, directory: Path, esi: Sequence[Path] | None) -> None:
        self.directory = directory
        self.esi = list(esi) if esi else None
        self._catalog: EsiCatalog | None = None
        self.types: dict[str, EditedType] = {}
        self._files: dict[Path, list[str]] = {}
        self.load()

    def load(self) -> None:
        """(Re)read every terminal file of the directory."""
        self.types.clear()
        self._files.clear()
        paths = terminal_paths([self.directory]) if any(self._yaml_files()) else []
        for path in paths:
            found = read_terminal_file(path)
            self._files[path] = list(found)
            for name, terminal in found.items():
                self.types[name] = EditedType(name, path, terminal, terminal)

    def _yaml_files(self) -> list[Path]:
        return [p for p in self.directory.glob("*.y*ml") if p.is_file()]

    def get(self, name: str) -> EditedType:
        if name not in self.types:
            raise UserError(f"no terminal type {name!r} in {self.directory}")
        return self.types[name]

    def catalog(self) -> EsiCatalog:
        """The ESI catalog, read on first use (`--esi`, else the cached zip,
        else in a checkout the ESI subset it ships)."""
        if self._catalog is None:
            self._catalog = open_catalog(self.esi or checkout_default_esi())
        return self._catalog

    def search(self, text: str) -> list[CatalogEntry]:
        """Types whose name, description or group type holds `text`."""
        wanted = text.strip().casefold()
        found: list[CatalogEntry] = []
        for entry in self.catalog().newest():
            if not entry.parses:
                continue
            fields = (entry.type_name, entry.description, entry.group_type)
            if all(part in " ".join(fields).casefold() for part in wanted.split()):
                found.append(entry)
            if len(found) >= SEARCH_LIMIT:
                break
        return found

    def add_type(self, type_name: str) -> EditedType:
        """Generate a type from the ESI (default choices: its default PDO
        group selected); its file is written only when it is saved."""
        entry = self.catalog().find(type_name)
        name = entry.type_name
        path = file_in(self.directory, terminal_file_name(name))
        if name in self.types or path.exists():
            raise UserError(f"{path.name} exists already", path=path)
        terminal = terminal_from_esi(self.catalog().load(name, entry.revision))
        self._files[path] = [name]
        self.types[name] = EditedType(name, path, None, terminal)
        return self.types[name]

    def apply(self, name: str, edit: Callable[[TerminalType], TerminalType]) -> None:
        """Make a choice (a `terminals.selection` function); not saved yet.

        `SelectionError` propagates for the page to show next to its field."""
        edited = self.get(name)
        edited.current = edit(edited.current)

    def revert(self, name: str) -> None:
        """Forget the edits not saved (a type not saved yet: the type)."""
        edited = self.get(name)
        if edited.saved is None:
            del self.types[name]
            del self._files[edited.path]
            return
        edited.current = edited.saved

    def _file_types(self, edited: EditedType) -> dict[str, TerminalType]:
        return {n: self.types[n].current for n in self._files[edited.path]}

    def diff(self, name: str) -> str:
        """The unified diff a save would make to the file ("" for none)."""
        edited = self.get(name)
        before = old_text(edited.path) or ""
        after, _ = file_text(self._file_types(edited), before)
        lines = difflib.unified_diff(
            before.splitlines(keepends=True),
            after.splitlines(keepends=True),
            fromfile=f"{edited.path.name} (on disk)",
            tofile=f"{edited.path.name} (edited)",
        )
        return "".join(lines)

    def save(self, name: str) -> SavedFile:
        """Write the type's file as the CLI would (comments kept)."""
        edited = self.get(name)
        saved = save_terminals(edited.path, self._file_types(edited))
        for other in self._files[edited.path]:
            self.types[other].saved = self.types[other].current
        return saved
