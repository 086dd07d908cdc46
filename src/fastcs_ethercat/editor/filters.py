"""Which rows of a type's page a filter shows: symbols, their members and
CoE objects with their sub-indices, by text and by selected or not.

No web code: the page asks, row by row. A row matches when every word of
the text is in its names (any case); a symbol or object whose own name
matches shows all its members or sub-indices, else only the matching ones.
"""

from __future__ import annotations

from dataclasses import dataclass

from fastcs_ethercat.terminals.model import (
    CoeObject,
    CoeSubItem,
    SymbolMember,
    SymbolNode,
)

FILTER_STATES = ("all", "selected", "unselected")


@dataclass(frozen=True)
class RowFilter:
    text: str = ""
    state: str = "all"

    @property
    def narrows(self) -> bool:
        """True when the text leaves rows out (the page then opens the
        symbols and objects whose inner rows match)."""
        return bool(self.text.split())

    def _matches(self, *names: str) -> bool:
        haystack = " ".join(names).casefold()
        return all(word in haystack for word in self.text.casefold().split())

    def _state_fits(self, selected: bool) -> bool:
        return self.state == "all" or selected == (self.state == "selected")

    def _symbol_matches(self, node: SymbolNode) -> bool:
        return self._matches(node.name_template, node.fastcs_name, node.type_name)

    def members(self, node: SymbolNode) -> list[SymbolMember]:
        """The members to list under a shown symbol."""
        if self._symbol_matches(node):
            return list(node.members)
        return [m for m in node.members if self._matches(m.shown_name, m.fastcs_name)]

    def shows_symbol(self, node: SymbolNode) -> bool:
        return self._state_fits(node.selected) and bool(
            self._symbol_matches(node) or self.members(node)
        )

    def _object_matches(self, obj: CoeObject) -> bool:
        return self._matches(f"0x{obj.index:04x}", obj.name, obj.fastcs_name)

    def sub_items(self, obj: CoeObject) -> list[CoeSubItem]:
        """The sub-indices to list under a shown object."""
        if self._object_matches(obj):
            return list(obj.sub_items)
        return [
            sub
            for sub in obj.sub_items
            if self._matches(f"{sub.subindex:02x}", sub.name, sub.fastcs_name)
        ]

    def shows_coe(self, obj: CoeObject) -> bool:
        return self._state_fits(obj.selected) and bool(
            self._object_matches(obj) or self.sub_items(obj)
        )
