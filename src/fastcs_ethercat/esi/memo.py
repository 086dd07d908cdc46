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

from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from lxml import etree

from .model import (
    EsiCoeObject,
    EsiDataType,
    EsiDcOpMode,
    EsiEntry,
    EsiPdo,
    EsiPdoGroup,
    EsiSyncManager,
)
from .xmltext import Element

if TYPE_CHECKING:
    from .dictionary_types import Defaults, ObjectFacts, Rows, TypeTable

Parsed = TypeVar("Parsed")

GroupsKey = tuple[str, tuple[int, ...], tuple[EsiSyncManager, ...]]
"""What PDO groups depend on: the `TwinCAT` element's text ("" without
one), the identities of the device's PDOs (shared objects of the memo) and
its sync managers."""


def element_key(element: Element) -> str:
    """The serialised element (tag, attributes, content; not its tail)."""
    return etree.tostring(element, encoding="unicode", with_tail=False)


def child_keys(key: str, tag: str, count: int) -> list[str] | None:
    """Keys for the `count` elements `<tag>` inside the element serialised
    as `key` (its children, or deeper), cut from it rather than serialised
    again; None if they cannot be.

    In serialised XML a `<` is always markup (an attribute's `>` is escaped,
    so the element's own start tag ends at the first `>`). When what follows
    holds exactly `count` times `<tag` and as many `</tag>`, those are the
    elements' start and end tags, none empty, nested or named `tagX`: the
    i-th `</tag>` closes the i-th element, and each key is that element's
    text up to its end tag.
    """
    pieces = key.split(f"</{tag}>")
    start = f"<{tag}"
    own_end = key.find(">")
    if len(pieces) != count + 1 or key.count(start, own_end) != count:
        return None
    pieces.pop()
    if pieces:
        pieces[0] = key[key.index(start, own_end) : len(pieces[0])]
    return [
        piece if piece.startswith(start) else piece[piece.index(start) :]
        for piece in pieces
    ]


def shared(
    parse: Callable[[Element], Parsed],
    elements: list[Element],
    tag: str,
    key: str,
    known: dict[str, Parsed] | None,
) -> list[Parsed]:
    """`parse` of each of `elements` (every `<tag>` inside the element
    serialised as `key`); with a memo table `known`, each distinct one is
    parsed once (its key cut by `child_keys`; where they cannot be cut,
    each is parsed)."""
    keys = child_keys(key, tag, len(elements)) if known is not None else None
    if keys is None or known is None:
        return [parse(element) for element in elements]
    values: list[Parsed] = []
    for element, element_key in zip(elements, keys, strict=True):
        value = known.get(element_key)
        if value is None:
            value = known[element_key] = parse(element)
        values.append(value)
    return values


class ParseMemo:
    """Parsed PDOs, data types, their tables and CoE objects."""

    __slots__ = (
        "data_type",
        "data_types",
        "dc_op_modes",
        "entries",
        "groups",
        "object_facts",
        "object_rests",
        "object_tables",
        "objects",
        "objects_in_table",
        "pdos",
        "rows",
        "sub_item_defaults",
    )

    def __init__(self) -> None:
        self.pdos: dict[str, EsiPdo] = {}
        self.dc_op_modes: dict[str, tuple[EsiDcOpMode, ...]] = {}
        """Dc text -> its parsed OpModes."""
        self.groups: dict[GroupsKey, tuple[EsiPdoGroup, ...]] = {}
        """(TwinCAT text, PDO identities, sync managers) -> PDO groups."""
        self.entries: dict[str, EsiEntry] = {}
        """PDO Entry text (see `child_keys`) -> the parsed entry."""
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
        self.sub_item_defaults: dict[str, tuple[str, Defaults]] = {}
        """`Object/Info/SubItem` text (see `child_keys`) -> its name and
        defaults."""
        self.object_rests: dict[str, ObjectFacts] = {}
        """Object text after its leading Index and Name (see
        `dictionary.read_object`) -> the facts of one such object."""
        self.objects_in_table: dict[tuple[str, int], EsiCoeObject] = {}
        """(Object text, identity of the type table) -> object: the same
        object with the same table is the same object, without resolving
        its type again."""
        self.object_tables: dict[tuple[str, int], dict[int, EsiCoeObject]] = {}
        """(Objects text, identity of the type table) -> objects by index:
        whole dictionaries repeat (225 in the shared files, 135 distinct)."""
