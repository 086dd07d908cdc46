"""`Profile/Dictionary` -> data types and CoE objects.

A CoE object names a data type; a record type lists its sub-items (with
SubIdx), and an array member (a SubItem without SubIdx, e.g. "Elements" of
`DT1C12`) stands for one sub-index per array element. The object's own
`Info/SubItem`s carry defaults by sub-item *name*, often only for some of
them. This module resolves all of that into flat `EsiCoeSubItem`s.

Type names must resolve: a name that is neither defined in the dictionary nor
an IEC/ETG base type is an error of the device (the real files define every
type they use in `DataTypes`; PDO entries may use base types such as REAL).
"""

from __future__ import annotations

import re

from .dictionary_types import Defaults, ObjectFacts, Rows, TypeTable
from .memo import ParseMemo, child_keys, element_key, shared
from .model import (
    Access,
    EsiCoeObject,
    EsiCoeSubItem,
    EsiDataType,
    EsiDataTypeSubItem,
    EsiEnumItem,
    new_record,
)
from .xmltext import (
    NUMBERS,
    Element,
    EsiFormatError,
    check_bits,
    fail,
    int_of,
    text_of,
)

_BASE_TYPE = re.compile(
    r"(?:BOOL(?:EAN)?|BIT\d*|BITARR\d+|BYTE|WORD|DWORD|LWORD"
    r"|U?(?:S|D|L)?INT(?:8|16|24|32|40|48|56|64)?|U?INT\d+"
    r"|L?REAL(?:32|64)?|FLOAT|DOUBLE|GUID|TIME_OF_DAY|TIME_DIFFERENCE"
    r"|(?:VISIBLE_|OCTET_|UNICODE_)?STRING(?:\(\d+\))?"
    r"|ARRAY \[-?\d+\.\.-?\d+\] OF .+)"
)
_ACCESS: dict[str, Access] = {"ro": "ro", "rw": "rw", "wo": "wo"}


def is_base_type(name: str) -> bool:
    """True for built-in type names a file may use without defining them."""
    return _BASE_TYPE.fullmatch(name) is not None


def _flags(element: Element) -> tuple[Access | None, str | None, str | None]:
    """(access, pdo mapping, category) of a `<Flags>` element."""
    access: Access | None = None
    pdo_mapping: str | None = None
    category: str | None = None
    for child in element:
        tag = child.tag
        if tag == "Access":
            access = _ACCESS.get(text_of(child).lower())
        elif tag == "PdoMapping":
            pdo_mapping = text_of(child) or None
        elif tag == "Category":
            category = text_of(child) or None
    return access, pdo_mapping, category


def _data_type_sub_item(element: Element, owner: str) -> EsiDataTypeSubItem:
    subindex: int | None = None
    name = ""
    type_name: str | None = None
    bit_size = 0
    bit_offset = 0
    access: Access | None = None
    pdo_mapping: str | None = None
    for child in element:
        tag = child.tag
        if tag == "SubIdx":
            subindex = NUMBERS.get(child.text)
            if subindex is None:
                subindex = int_of(child, f"SubIdx of a sub-item of {owner}")
        elif tag == "Name":
            name = text_of(child)
        elif tag == "Type":
            type_name = text_of(child)
        elif tag == "BitSize":
            bit_size = NUMBERS.get(child.text)
            if bit_size is None:
                bit_size = int_of(child, f"BitSize of {owner}.{name}")
        elif tag == "BitOffs":
            bit_offset = NUMBERS.get(child.text)
            if bit_offset is None:
                bit_offset = int_of(child, f"BitOffs of {owner}.{name}")
        elif tag == "Flags":
            access, pdo_mapping, _ = _flags(child)
    if not type_name:
        raise fail(element, f"sub-item {name!r} of data type {owner} has no <Type>")
    check_bits(element, f"BitSize of {owner}.{name}", bit_size)
    check_bits(element, f"BitOffs of {owner}.{name}", bit_offset)
    return new_record(
        EsiDataTypeSubItem,
        (subindex, name, type_name, bit_size, bit_offset, access, pdo_mapping),
    )


def parse_data_type(element: Element) -> EsiDataType:
    """One `<DataType>` of `DataTypes`."""
    name: str | None = None
    bit_size: int | None = None
    base_type: str | None = None
    enum_items: list[EsiEnumItem] = []
    sub_elements: list[Element] = []
    array_lbound: int | None = None
    array_elements: int | None = None
    for child in element:
        tag = child.tag
        if tag == "SubItem":
            sub_elements.append(child)
        elif tag == "Name":
            name = text_of(child)
        elif tag == "BitSize":
            bit_size = check_bits(
                child, "data type BitSize", int_of(child, "data type BitSize")
            )
        elif tag == "BaseType":
            base_type = text_of(child) or None
        elif tag == "EnumInfo":
            enum_items.append(_enum_item(child))
        elif tag == "ArrayInfo" and array_elements is None:
            for info in child:
                if info.tag == "LBound":
                    array_lbound = int_of(info, "ArrayInfo LBound")
                elif info.tag == "Elements":
                    array_elements = int_of(info, "ArrayInfo Elements")
    if not name:
        raise fail(element, "<DataType> has no <Name>")
    if bit_size is None:
        raise fail(element, f"data type {name} has no <BitSize>")
    return EsiDataType(
        name,
        bit_size,
        base_type,
        tuple(enum_items),
        tuple([_data_type_sub_item(sub, name) for sub in sub_elements]),
        array_lbound,
        array_elements,
    )


def _enum_item(element: Element) -> EsiEnumItem:
    text = ""
    value: int | None = None
    for child in element:
        if child.tag == "Text":
            text = text_of(child)
        elif child.tag == "Enum":
            value = int_of(child, "EnumInfo Enum")
    if value is None:
        raise fail(element, f"enum text {text!r} has no <Enum> value")
    return EsiEnumItem(value, text)


def parse_data_types(
    element: Element, memo: ParseMemo | None = None, key: str = ""
) -> dict[str, EsiDataType]:
    """`<DataTypes>` -> name -> type, checking that every reference resolves.

    With a `memo` and the element's `key`, each type is parsed once."""
    children = list(element.iterchildren("DataType"))
    known = memo.data_type if memo and key else None
    parsed = shared(parse_data_type, children, "DataType", key, known)
    types: dict[str, EsiDataType] = {}
    for data_type in parsed:
        types.setdefault(data_type.name, data_type)
    for data_type in types.values():
        for sub in data_type.sub_items:
            if sub.type_name not in types and not is_base_type(sub.type_name):
                raise _unknown_type(data_type, sub.type_name, children, parsed)
        base = data_type.base_type
        if base and base not in types and not is_base_type(base):
            raise _unknown_type(data_type, base, children, parsed)
    return types


def _unknown_type(
    data_type: EsiDataType,
    name: str,
    children: list[Element],
    parsed: list[EsiDataType],
) -> EsiFormatError:
    """The error for a reference to an undefined type, placed at the first
    definition of `data_type` (the one `parse_data_types` keeps)."""
    line = next(
        child.sourceline
        for child, found in zip(children, parsed, strict=True)
        if found.name == data_type.name
    )
    return EsiFormatError(
        f"data type {data_type.name} uses unknown data type {name!r}", line
    )


_DEFAULT_SLOTS = {
    "DefaultData": 0,
    "DefaultValue": 1,
    "MinValue": 2,
    "MaxValue": 3,
    "Unit": 4,
}
_NO_DEFAULTS: Defaults = [None] * len(_DEFAULT_SLOTS)


def _defaults(info: Element) -> Defaults:
    """The defaults an `Info` element gives (the last of each kind wins)."""
    found = _NO_DEFAULTS.copy()
    for child in info:
        slot = _DEFAULT_SLOTS.get(child.tag)
        if slot is not None:
            text = child.text
            found[slot] = (text.strip() or None) if text else None
    return found


_NO_TYPES = TypeTable({})


def _sub_item_defaults(element: Element) -> tuple[str, Defaults]:
    """Name and defaults of an object's `Info/SubItem`."""
    name = ""
    defaults = _NO_DEFAULTS
    for part in element:
        tag = part.tag
        if tag == "Name":
            text = part.text
            name = text.strip() if text else ""
        elif tag == "Info":
            defaults = _defaults(part)
    return name, defaults


def read_object(
    element: Element, memo: ParseMemo | None = None, key: str = ""
) -> ObjectFacts:
    """The facts of one `<Object>`; errors are placed. With a `memo` and the
    element's `key`, objects that differ only in their leading Index and
    Name (one per channel: #x6000, #x6010, ...) are read once, and each
    distinct `Info/SubItem` too."""
    rest = _after_index_and_name(element, key) if memo is not None else None
    if rest is None or memo is None:
        return _read_object(element, memo, key)
    name = text_of(element[1])
    shape = memo.object_rests.get(rest) if name else None
    if shape is not None:
        index = int_of(element[0], "object Index")
        return new_record(ObjectFacts, (index, name, *shape[2:]))
    facts = _read_object(element, memo, key)
    if name:
        memo.object_rests[rest] = facts
    return facts


def _after_index_and_name(element: Element, key: str) -> str | None:
    """The text (`key`) of an object after its first two children when they
    are a leaf `<Index>` and a leaf `<Name>`, and no other `<Index>` follows
    (it would win): all of its facts but those two. None otherwise."""
    if not key or len(element) < 2:
        return None
    index, name = element[0], element[1]
    if index.tag != "Index" or name.tag != "Name" or len(index) or len(name):
        return None
    rest = key[key.find("</Name>") + len("</Name>") :]
    return None if "<Index" in rest else rest


def _read_object(element: Element, memo: ParseMemo | None, key: str) -> ObjectFacts:
    """`read_object` without the shortcut for objects alike but for their
    Index and Name."""
    index: int | None = None
    name = ""
    type_name: str | None = None
    bit_size = 0
    info: Element | None = None
    access: Access | None = None
    pdo_mapping: str | None = None
    category: str | None = None
    for child in element:
        tag = child.tag
        if tag == "Index":
            index = int_of(child, "object Index")
        elif tag == "Name":
            if not name:
                name = text_of(child)
        elif tag == "Type":
            type_name = text_of(child)
        elif tag == "BitSize":
            bit_size = check_bits(
                child, "object BitSize", int_of(child, "object BitSize")
            )
        elif tag == "Info":
            info = child
        elif tag == "Flags":
            access, pdo_mapping, category = _flags(child)
    if index is None:
        raise fail(element, f"CoE object {name!r} has no <Index>")
    if not type_name:
        raise fail(element, f"CoE object #x{index:04x} {name!r} has no <Type>")
    default_data: str | None = None
    by_name: dict[str, Defaults] = {}
    if info is not None:
        sub_items: list[Element] = []
        for child in info:  # one loop: a tag filter costs more to set up
            if child.tag == "SubItem":
                sub_items.append(child)
            elif child.tag == "DefaultData":
                default_data = text_of(child) or None
        known = memo.sub_item_defaults if memo else None
        parsed = shared(_sub_item_defaults, sub_items, "SubItem", key, known)
        for sub_name, defaults in parsed:
            if sub_name not in by_name:
                by_name[sub_name] = defaults
    return ObjectFacts(
        index,
        name,
        type_name,
        bit_size,
        access,
        pdo_mapping,
        category,
        default_data,
        by_name,
    )


def object_type(
    facts: ObjectFacts, element: Element, table: TypeTable, check_types: bool
) -> tuple[EsiDataType | None, Rows]:
    """The object's data type and its expansion; an unknown type is an error."""
    data_type = table.types.get(facts.type_name)
    if data_type is None:
        if check_types and not is_base_type(facts.type_name):
            raise fail(
                element,
                f"CoE object #x{facts.object_index:04x} {facts.name!r} uses "
                f"unknown data type {facts.type_name!r}",
            )
        return None, ()
    return data_type, table.expand(data_type) if data_type.sub_items else ()


def resolve_object(
    facts: ObjectFacts, data_type: EsiDataType | None, rows: Rows
) -> EsiCoeObject:
    """The object with its sub-items resolved through its data type."""
    index, access = facts.object_index, facts.access
    by_name = facts.defaults_by_name
    sub_items: list[EsiCoeSubItem] = []
    for (
        subindex,
        sub_name,
        bits,
        offset,
        sub_type,
        sub_access,
        sub_pdo_mapping,
        enum_items,
    ) in rows:
        defaults = by_name.get(sub_name, _NO_DEFAULTS)
        sub_items.append(
            new_record(
                EsiCoeSubItem,
                (
                    index,
                    subindex,
                    sub_name,
                    sub_type,
                    bits,
                    offset,
                    sub_access or access,
                    sub_pdo_mapping,
                    defaults[0],
                    defaults[1],
                    defaults[2],
                    defaults[3],
                    defaults[4],
                    enum_items,
                ),
            )
        )
    return new_record(
        EsiCoeObject,
        (
            index,
            facts.name,
            facts.type_name,
            facts.bit_size,
            access,
            facts.pdo_mapping,
            facts.category,
            facts.default_data,
            tuple(sub_items),
            data_type.enum_items if data_type is not None else (),
        ),
    )


def parse_object(element: Element, table: TypeTable, check_types: bool) -> EsiCoeObject:
    """One `<Object>`, sub-items resolved through its data type."""
    facts = read_object(element)
    return resolve_object(facts, *object_type(facts, element, table, check_types))


def _type_table(element: Element, memo: ParseMemo | None) -> TypeTable:
    """The `<DataTypes>` table, parsed once per memo."""
    if memo is None:
        return TypeTable(parse_data_types(element))
    key = element_key(element)
    table = memo.data_types.get(key)
    if table is None:
        types = parse_data_types(element, memo, key)
        table = memo.data_types[key] = TypeTable(types, memo.rows)
    return table


def _shared_object(
    element: Element, key: str, table: TypeTable, check: bool, memo: ParseMemo
) -> EsiCoeObject:
    """One `<Object>` (text `key`) through `memo`: its facts read once, the
    object resolved once per data type and expansion it meets."""
    facts = memo.object_facts.get(key)
    if facts is None:
        facts = memo.object_facts[key] = read_object(element, memo, key)
    data_type, rows = object_type(facts, element, table, check)
    meaning = (key, id(data_type), id(rows))
    coe_object = memo.objects.get(meaning)
    if coe_object is None:
        coe_object = memo.objects[meaning] = resolve_object(facts, data_type, rows)
    return coe_object


def _objects(
    element: Element, table: TypeTable, check: bool, memo: ParseMemo | None
) -> dict[int, EsiCoeObject]:
    """`<Objects>` -> objects by index (the first of an index wins)."""
    objects: dict[int, EsiCoeObject] = {}
    if memo is None:
        for child in element.iterchildren("Object"):
            coe_object = parse_object(child, table, check)
            objects.setdefault(coe_object.index, coe_object)
        return objects
    key = element_key(element)
    table_key = (key, id(table))
    known = memo.object_tables.get(table_key)
    if known is not None:
        return dict(known)
    children = list(element.iterchildren("Object"))
    keys = child_keys(key, "Object", len(children))
    if keys is None:
        keys = [element_key(child) for child in children]
    table_id = id(table)
    for child, child_key in zip(children, keys, strict=True):
        in_table = (child_key, table_id)
        coe_object = memo.objects_in_table.get(in_table)
        if coe_object is None:
            coe_object = memo.objects_in_table[in_table] = _shared_object(
                child, child_key, table, check, memo
            )
        objects.setdefault(coe_object.index, coe_object)
    memo.object_tables[table_key] = objects
    return dict(objects)


def parse_dictionary(
    element: Element, memo: ParseMemo | None = None
) -> tuple[dict[str, EsiDataType], dict[int, EsiCoeObject]]:
    """`<Dictionary>` -> (data types by name, CoE objects by index)."""
    types_element: Element | None = None
    objects_element: Element | None = None
    for child in element:
        tag = child.tag
        if tag == "DataTypes" and types_element is None:
            types_element = child
        elif tag == "Objects" and objects_element is None:
            objects_element = child
    table = _NO_TYPES if types_element is None else _type_table(types_element, memo)
    objects: dict[int, EsiCoeObject] = {}
    if objects_element is not None:
        objects = _objects(objects_element, table, types_element is not None, memo)
    return dict(table.types), objects
