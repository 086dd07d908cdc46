"""The shapes the object dictionary parser makes and its memo keeps: an
`Info`'s defaults, a record type's sub-index rows, an object's own facts.

Below both `dictionary` (which fills them) and `memo` (which shares them
between devices), so neither imports the other's types back.
"""

from __future__ import annotations

from typing import NamedTuple

from .model import Access, EsiDataType, EsiEnumItem

Defaults = list[str | None]
"""`DefaultData`, `DefaultValue`, `MinValue`, `MaxValue`, `Unit` of an `Info`:
the order of those fields in `EsiCoeSubItem`."""

Expansion = tuple[
    int, str, int, int, str, Access | None, str | None, tuple[EsiEnumItem, ...]
]
"""(subindex, name, bit size, bit offset, type, access, pdo mapping, enum
items) of one sub-index of an object of a record or array type."""


Rows = tuple[Expansion, ...]


class TypeTable:
    """A device's data types, and how each record type expands into
    sub-indices (worked out once per type, not once per object)."""

    __slots__ = ("expansions", "rows", "types")

    def __init__(
        self, types: dict[str, EsiDataType], rows: dict[Rows, Rows] | None = None
    ) -> None:
        self.types = types
        self.rows: dict[Rows, Rows] = {} if rows is None else rows
        """Expansions by value, shared by tables: equal ones are one object."""
        self.expansions: dict[str, Rows] = {}

    def expand(self, data_type: EsiDataType) -> Rows:
        """One row per sub-index of an object of `data_type`; tables sharing
        `rows` give the same object for equal expansions."""
        rows = self.expansions.get(data_type.name)
        if rows is None:
            rows = tuple(self._expand(data_type))
            rows = self.expansions[data_type.name] = self.rows.setdefault(rows, rows)
        return rows

    def _enum_items(self, type_name: str) -> tuple[EsiEnumItem, ...]:
        data_type = self.types.get(type_name)
        return data_type.enum_items if data_type is not None else ()

    def _expand(self, data_type: EsiDataType) -> list[Expansion]:
        types = self.types
        rows: list[Expansion] = []
        for item in data_type.sub_items:
            access, pdo_mapping = item.access, item.pdo_mapping
            if item.subindex is not None:
                rows.append(
                    (
                        item.subindex,
                        item.name,
                        item.bit_size,
                        item.bit_offset,
                        item.type_name,
                        access,
                        pdo_mapping,
                        self._enum_items(item.type_name),
                    )
                )
                continue
            array = types.get(item.type_name)
            if array is None or array.array_elements is None:
                continue
            count = array.array_elements
            first = array.array_lbound if array.array_lbound is not None else 1
            element_type = array.base_type or item.type_name
            base = types.get(element_type)
            element_bits = (
                base.bit_size
                if base is not None
                else (array.bit_size // count if count else 0)
            )
            enum_items = self._enum_items(element_type)
            for position in range(count):
                subindex = first + position
                rows.append(
                    (
                        subindex,
                        f"SubIndex {subindex:03d}",
                        element_bits,
                        item.bit_offset + position * element_bits,
                        element_type,
                        access,
                        pdo_mapping,
                        enum_items,
                    )
                )
        return rows


class ObjectFacts(NamedTuple):
    """What an `<Object>` says by itself, before its data type resolves it
    (objects repeat more often than with the same types around them)."""

    object_index: int
    name: str
    type_name: str
    bit_size: int
    access: Access | None
    pdo_mapping: str | None
    category: str | None
    default_data: str | None
    defaults_by_name: dict[str, Defaults]
    """`Info/SubItem` defaults by sub-item name (the first of a name wins)."""
