"""All loaded terminal types, found by name or by the identity a terminal reports.

A live terminal reports vendor, product code and revision. Beckhoff's
revision number holds the revision in its high 16 bits and the type variant
(`-0010` -> 10) in its low 16 bits, so a description of an older revision of
the same variant is the nearest fit when the exact revision is missing; a
different variant never fits (EL3356-0010 is not an EL3356-0000).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.model import TerminalType


@dataclass(frozen=True, slots=True)
class RegisteredTerminal:
    """One terminal type and the file it came from."""

    type_name: str
    terminal: TerminalType
    path: Path


@dataclass(frozen=True, slots=True)
class RegistryMatch:
    """The description chosen for a live terminal's identity."""

    type_name: str
    terminal: TerminalType
    path: Path
    exact: bool
    """False when only an older revision of the same variant was found."""
    requested_revision: int


def variant_of(revision: int) -> int:
    """Low 16 bits of a Beckhoff revision number: the type variant."""
    return revision & 0xFFFF


class TerminalRegistry:
    """Terminal types by name and identity; duplicates are user errors."""

    def __init__(self, items: Iterable[RegisteredTerminal]) -> None:
        self._by_name: dict[str, RegisteredTerminal] = {}
        by_identity: dict[tuple[int, int, int], RegisteredTerminal] = {}
        for item in items:
            earlier = self._by_name.get(item.type_name)
            if earlier is not None:
                raise UserError(
                    f"terminal type {item.type_name} is also defined in {earlier.path}",
                    path=item.path,
                    where=item.type_name,
                )
            identity = item.terminal.identity
            key = (identity.vendor_id, identity.product_code, identity.revision_number)
            clash = by_identity.get(key)
            if clash is not None:
                raise UserError(
                    f"{item.type_name} has the same identity (product code "
                    f"0x{key[1]:08x}, revision 0x{key[2]:08x}) as "
                    f"{clash.type_name} in {clash.path}",
                    path=item.path,
                    where=item.type_name,
                )
            self._by_name[item.type_name] = item
            by_identity[key] = item

    def __len__(self) -> int:
        return len(self._by_name)

    def __iter__(self) -> Iterator[RegisteredTerminal]:
        return iter(self._by_name.values())

    def __contains__(self, type_name: object) -> bool:
        return type_name in self._by_name

    def type_names(self) -> list[str]:
        return sorted(self._by_name)

    def get(self, type_name: str) -> RegisteredTerminal:
        """The terminal type called `type_name`; KeyError if unknown."""
        return self._by_name[type_name]

    def lookup(
        self, product_code: int, revision: int, vendor_id: int | None = None
    ) -> RegistryMatch | None:
        """Exact identity, else the newest older revision of the same variant."""
        candidates = [
            item
            for item in self._by_name.values()
            if item.terminal.identity.product_code == product_code
            and (vendor_id is None or item.terminal.identity.vendor_id == vendor_id)
        ]
        for item in candidates:
            if item.terminal.identity.revision_number == revision:
                return self._match(item, revision, exact=True)
        older = [
            item
            for item in candidates
            if item.terminal.identity.revision_number < revision
            and variant_of(item.terminal.identity.revision_number)
            == variant_of(revision)
        ]
        if not older:
            return None
        best = max(older, key=lambda item: item.terminal.identity.revision_number)
        return self._match(best, revision, exact=False)

    @staticmethod
    def _match(
        item: RegisteredTerminal, revision: int, *, exact: bool
    ) -> RegistryMatch:
        return RegistryMatch(
            type_name=item.type_name,
            terminal=item.terminal,
            path=item.path,
            exact=exact,
            requested_revision=revision,
        )
