"""Reuse of parsed elements within one document.

Beckhoff repeats the same PDOs, data types and CoE objects in every revision
of a type (the shared files hold 3706 PDOs but only 1311 distinct ones,
10958 CoE objects but 3781 distinct ones). Serialising an element is far
cheaper than parsing it, so identical elements are parsed once per document,
keyed by their text. Only successes are remembered: a broken element is
parsed (and reported, with its own line) every time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from lxml import etree

from .model import EsiCoeObject, EsiPdo
from .xmltext import Element

if TYPE_CHECKING:
    from .dictionary import ObjectFacts, TypeTable


def element_key(element: Element) -> str:
    """The serialised element (tag, attributes, content; not its tail)."""
    return etree.tostring(element, encoding="unicode", with_tail=False)


class ParseMemo:
    """Parsed PDOs, data-type tables and CoE objects of one document."""

    __slots__ = ("data_types", "object_facts", "objects", "pdos")

    def __init__(self) -> None:
        self.pdos: dict[str, EsiPdo] = {}
        self.data_types: dict[str, TypeTable] = {}
        """DataTypes text -> the parsed table (numbered in this document)."""
        self.object_facts: dict[str, ObjectFacts] = {}
        """Object text -> what the object itself says (before its type)."""
        self.objects: dict[tuple[int, str], EsiCoeObject] = {}
        """(data-type table number, Object text) -> object: an object's
        meaning depends on the types it refers to."""
