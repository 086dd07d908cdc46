"""All loaded terminal types, found by name or by the identity a terminal reports.

A live terminal reports vendor, product code and revision. Beckhoff's
revision number holds the revision in its high 16 bits and the type variant
(`-0010` -> 10) in its low 16 bits. A rack runs many revisions older and
newer than the one YAML per type, so when the exact revision has no YAML the
nearest revision of the same product code stands in (the IOC then serves
only the symbols the live table has, by name): first within the same
variant, the older on a tie, then any variant of that product code. Only a
product code with no YAML at all has no match.
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
    """False when only another revision of the product code was found."""
    requested_revision: int

    @property
    def revision(self) -> int:
        """The revision the chosen YAML describes."""
        return self.terminal.identity.revision_number


def variant_of(revision: int) -> int:
    """Low 16 bits of a Beckhoff revision number: the type variant."""
    return revision & 0xFFFF


def revision_distance(described: int, wanted: int) -> tuple[int, int, int]:
    """How far revision `described` is from `wanted`, the smallest nearest:
    another variant is farther than any revision of the same variant, the
    older of two equally far revisions is nearer."""
    return (
        int(variant_of(described) != variant_of(wanted)),
        abs((described >> 16) - (wanted >> 16)),
        int(described > wanted),
    )


class TerminalRegistry:
    """Terminal types by name and identity; duplicates are user errors.

    A type may be described at several revisions (files of its own, e.g. a
    site's YAML of an older revision beside the shipped one): `lookup`
    chooses among all of them; `get` gives the first loaded of the name.
    """

    def __init__(self, items: Iterable[RegisteredTerminal]) -> None:
        self._by_name: dict[str, RegisteredTerminal] = {}
        self._items: list[RegisteredTerminal] = []
        by_identity: dict[tuple[int, int, int], RegisteredTerminal] = {}
        for item in items:
            identity = item.terminal.identity
            key = (identity.vendor_id, identity.product_code, identity.revision_number)
            clash = by_identity.get(key)
            if clash is not None and clash.type_name == item.type_name:
                raise UserError(
                    f"terminal type {item.type_name} is also defined in {clash.path}",
                    path=item.path,
                    where=item.type_name,
                )
            if clash is not None:
                raise UserError(
                    f"{item.type_name} has the same identity (product code "
                    f"0x{key[1]:08x}, revision 0x{key[2]:08x}) as "
                    f"{clash.type_name} in {clash.path}",
                    path=item.path,
                    where=item.type_name,
                )
            earlier = self._by_name.get(item.type_name)
            if earlier is not None and (
                earlier.terminal.identity.product_code != identity.product_code
            ):
                raise UserError(
                    f"terminal type {item.type_name} is also defined in "
                    f"{earlier.path} with another product code",
                    path=item.path,
                    where=item.type_name,
                )
            self._by_name.setdefault(item.type_name, item)
            self._items.append(item)
            by_identity[key] = item

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self) -> Iterator[RegisteredTerminal]:
        return iter(self._items)

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
        """Exact identity, else the nearest revision of the product code."""
        candidates = [
            item
            for item in self._items
            if item.terminal.identity.product_code == product_code
            and (vendor_id is None or item.terminal.identity.vendor_id == vendor_id)
        ]
        if not candidates:
            return None
        best = min(
            candidates,
            key=lambda item: revision_distance(
                item.terminal.identity.revision_number, revision
            ),
        )
        exact = best.terminal.identity.revision_number == revision
        return self._match(best, revision, exact=exact)

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
