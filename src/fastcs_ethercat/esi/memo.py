"""Reuse of parsed elements within one document.

Beckhoff repeats the same PDOs, data types and CoE objects in every revision
of a type (the shared files hold 3706 PDOs but only 1212 distinct ones, 10958
CoE objects but 3314 distinct ones). Serialising an element is far cheaper
than parsing it into dataclasses, so identical elements are parsed once per
document, keyed by their bytes. Only successes are remembered: a broken
element is parsed (and reported, with its own line) every time.
"""

from __future__ import annotations

from lxml import etree

from .model import EsiCoeObject, EsiDataType, EsiPdo
from .xmltext import Element


def element_key(element: Element) -> bytes:
    """The serialised element (tag, attributes, content; not its tail)."""
    return etree.tostring(element, with_tail=False)


class ParseMemo:
    """Parsed PDOs, data-type tables and CoE objects of one document."""

    __slots__ = ("data_types", "objects", "pdos")

    def __init__(self) -> None:
        self.pdos: dict[bytes, EsiPdo] = {}
        self.data_types: dict[bytes, tuple[int, dict[str, EsiDataType]]] = {}
        """DataTypes bytes -> (table id, table)."""
        self.objects: dict[tuple[int, bytes], EsiCoeObject] = {}
        """(data-type table id, Object bytes) -> object: an object's meaning
        depends on the types it refers to."""
