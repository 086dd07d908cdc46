"""Reuse of parsed elements.

Beckhoff repeats the same PDOs, data types and CoE objects in every revision
of a type, and some files repeat devices of others (the shared files hold
3706 PDOs but only 1212 distinct ones, 10958 CoE objects but 3314 distinct
ones, 31514 data types but 1241 distinct ones in 74 distinct tables).
Serialising an element is several times cheaper than parsing it, so
identical elements are parsed once, keyed by their text: the text says all
the parser reads (entities are not resolved), so one memo serves every
document of a parse. Only successes are remembered: a broken element is
parsed (and reported, with its own line) every time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from lxml import etree

from .model import EsiCoeObject, EsiDataType, EsiPdo
from .xmltext import Element

if TYPE_CHECKING:
    from .dictionary import ObjectFacts, Rows, TypeTable


def element_key(element: Element) -> str:
    """The serialised element (tag, attributes, content; not its tail)."""
    return etree.tostring(element, encoding="unicode", with_tail=False)


def child_keys(key: str, tag: str, count: int) -> list[str] | None:
    """Keys for the `count` children `<tag>` of the element serialised as
    `key`, cut from it rather than serialised again; None if they cannot be.

    In serialised XML a `<` is always markup, so the i-th `</tag>` closes the
    i-th child when `key` holds exactly `count` start tags `<tag` (no nested
    or other ones). Each key runs from the end of the previous child (or of
    the parent's start tag) to its own end: the child is its last element.
    """
    pieces = key.split(f"</{tag}>")
    if len(pieces) != count + 1:
        return None
    if key.count(f"<{tag}>") + key.count(f"<{tag} ") != count:
        return None
    first = pieces[0]
    pieces[0] = first[first.index(">") + 1 :]
    pieces.pop()
    return pieces


class ParseMemo:
    """Parsed PDOs, data types, their tables and CoE objects."""

    __slots__ = ("data_type", "data_types", "object_facts", "objects", "pdos", "rows")

    def __init__(self) -> None:
        self.pdos: dict[str, EsiPdo] = {}
        self.data_types: dict[str, TypeTable] = {}
        """DataTypes text -> the parsed table."""
        self.data_type: dict[str, EsiDataType] = {}
        """DataType text (see `child_keys`) -> the parsed type."""
        self.object_facts: dict[str, ObjectFacts] = {}
        """Object text (see `child_keys`) -> what the object itself says
        (before its type)."""
        self.rows: dict[Rows, Rows] = {}
        """Sub-index expansions of record types by value (see `TypeTable`)."""
        self.objects: dict[tuple[str, int, int], EsiCoeObject] = {}
        """(Object text, identities of its data type and of its expansion) ->
        object: an object's meaning depends on the types it refers to, and
        both are shared objects held by this memo."""
