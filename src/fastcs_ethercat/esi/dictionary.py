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
from collections.abc import Mapping

from .memo import ParseMemo, element_key
from .model import (
    Access,
    EsiCoeObject,
    EsiCoeSubItem,
    EsiDataType,
    EsiDataTypeSubItem,
    EsiEnumItem,
)
from .xmltext import Element, EsiFormatError, fail, int_of, text_of

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
            subindex = int_of(child, f"SubIdx of a sub-item of {owner}")
        elif tag == "Name":
            name = text_of(child)
        elif tag == "Type":
            type_name = text_of(child)
        elif tag == "BitSize":
            bit_size = int_of(child, f"BitSize of {owner}.{name}")
        elif tag == "BitOffs":
            bit_offset = int_of(child, f"BitOffs of {owner}.{name}")
        elif tag == "Flags":
            access, pdo_mapping, _ = _flags(child)
    if not type_name:
        raise fail(element, f"sub-item {name!r} of data type {owner} has no <Type>")
    return EsiDataTypeSubItem(
        subindex=subindex,
        name=name,
        type_name=type_name,
        bit_size=bit_size,
        bit_offset=bit_offset,
        access=access,
        pdo_mapping=pdo_mapping,
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
        if tag == "Name":
            name = text_of(child)
        elif tag == "BitSize":
            bit_size = int_of(child, "data type BitSize")
        elif tag == "BaseType":
            base_type = text_of(child) or None
        elif tag == "EnumInfo":
            enum_items.append(_enum_item(child))
        elif tag == "SubItem":
            sub_elements.append(child)
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
        name=name,
        bit_size=bit_size,
        base_type=base_type,
        enum_items=tuple(enum_items),
        sub_items=tuple(_data_type_sub_item(sub, name) for sub in sub_elements),
        array_lbound=array_lbound,
        array_elements=array_elements,
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
    return EsiEnumItem(value=value, text=text)


def parse_data_types(element: Element) -> dict[str, EsiDataType]:
    """`<DataTypes>` -> name -> type, checking that every reference resolves."""
    types: dict[str, EsiDataType] = {}
    lines: dict[str, int | None] = {}
    for child in element:
        if child.tag == "DataType":
            data_type = parse_data_type(child)
            types.setdefault(data_type.name, data_type)
            lines.setdefault(data_type.name, child.sourceline)
    for data_type in types.values():
        referenced = [sub.type_name for sub in data_type.sub_items]
        if data_type.base_type:
            referenced.append(data_type.base_type)
        for name in referenced:
            if name not in types and not is_base_type(name):
                raise EsiFormatError(
                    f"data type {data_type.name} uses unknown data type {name!r}",
                    lines[data_type.name],
                )
    return types


class _InfoDefaults:
    """Defaults of one `Info/SubItem` (or an object's own `Info`)."""

    __slots__ = ("default_data", "default_value", "max_value", "min_value", "unit")

    def __init__(self, element: Element | None) -> None:
        self.default_data: str | None = None
        self.default_value: str | None = None
        self.min_value: str | None = None
        self.max_value: str | None = None
        self.unit: str | None = None
        if element is None:
            return
        for child in element:
            tag = child.tag
            if tag == "DefaultData":
                self.default_data = text_of(child) or None
            elif tag == "DefaultValue":
                self.default_value = text_of(child) or None
            elif tag == "MinValue":
                self.min_value = text_of(child) or None
            elif tag == "MaxValue":
                self.max_value = text_of(child) or None
            elif tag == "Unit":
                self.unit = text_of(child) or None


_NO_DEFAULTS = _InfoDefaults(None)


def _enum_items_of(
    type_name: str, types: Mapping[str, EsiDataType]
) -> tuple[EsiEnumItem, ...]:
    data_type = types.get(type_name)
    return data_type.enum_items if data_type is not None else ()


def _expand_sub_items(
    data_type: EsiDataType, types: Mapping[str, EsiDataType]
) -> list[tuple[EsiDataTypeSubItem, int, str, int, int, str]]:
    """(item, subindex, name, bit size, bit offset, type) per sub-index."""
    rows: list[tuple[EsiDataTypeSubItem, int, str, int, int, str]] = []
    for item in data_type.sub_items:
        if item.subindex is not None:
            rows.append(
                (
                    item,
                    item.subindex,
                    item.name,
                    item.bit_size,
                    item.bit_offset,
                    item.type_name,
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
        for position in range(count):
            subindex = first + position
            rows.append(
                (
                    item,
                    subindex,
                    f"SubIndex {subindex:03d}",
                    element_bits,
                    item.bit_offset + position * element_bits,
                    element_type,
                )
            )
    return rows


def parse_object(
    element: Element, types: Mapping[str, EsiDataType], check_types: bool
) -> EsiCoeObject:
    """One `<Object>`, sub-items resolved through its data type."""
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
            bit_size = int_of(child, "object BitSize")
        elif tag == "Info":
            info = child
        elif tag == "Flags":
            access, pdo_mapping, category = _flags(child)
    if index is None:
        raise fail(element, f"CoE object {name!r} has no <Index>")
    if not type_name:
        raise fail(element, f"CoE object #x{index:04x} {name!r} has no <Type>")
    data_type = types.get(type_name)
    if data_type is None and check_types and not is_base_type(type_name):
        raise fail(
            element,
            f"CoE object #x{index:04x} {name!r} uses unknown data type {type_name!r}",
        )
    own = _InfoDefaults(info)
    by_name: dict[str, _InfoDefaults] = {}
    if info is not None:
        for child in info:
            if child.tag == "SubItem":
                sub_name = ""
                sub_info: Element | None = None
                for part in child:
                    if part.tag == "Name":
                        sub_name = text_of(part)
                    elif part.tag == "Info":
                        sub_info = part
                by_name.setdefault(sub_name, _InfoDefaults(sub_info))
    sub_items: list[EsiCoeSubItem] = []
    if data_type is not None and data_type.sub_items:
        for item, subindex, sub_name, bits, offset, sub_type in _expand_sub_items(
            data_type, types
        ):
            defaults = by_name.get(sub_name, _NO_DEFAULTS)
            sub_items.append(
                EsiCoeSubItem(
                    index=index,
                    subindex=subindex,
                    name=sub_name,
                    type_name=sub_type,
                    bit_size=bits,
                    bit_offset=offset,
                    access=item.access or access,
                    pdo_mapping=item.pdo_mapping,
                    default_data=defaults.default_data,
                    default_value=defaults.default_value,
                    min_value=defaults.min_value,
                    max_value=defaults.max_value,
                    unit=defaults.unit,
                    enum_items=_enum_items_of(sub_type, types),
                )
            )
    return EsiCoeObject(
        index=index,
        name=name,
        type_name=type_name,
        bit_size=bit_size,
        access=access,
        pdo_mapping=pdo_mapping,
        category=category,
        default_data=own.default_data,
        sub_items=tuple(sub_items),
        enum_items=data_type.enum_items if data_type is not None else (),
    )


def parse_dictionary(
    element: Element, memo: ParseMemo | None = None
) -> tuple[dict[str, EsiDataType], dict[int, EsiCoeObject]]:
    """`<Dictionary>` -> (data types by name, CoE objects by index)."""
    types_element = element.find("DataTypes")
    types: dict[str, EsiDataType] = {}
    table_id = -1
    if types_element is not None:
        if memo is None:
            types = parse_data_types(types_element)
        else:
            key = element_key(types_element)
            cached = memo.data_types.get(key)
            if cached is None:
                cached = (len(memo.data_types), parse_data_types(types_element))
                memo.data_types[key] = cached
            table_id, types = cached
    objects: dict[int, EsiCoeObject] = {}
    objects_element = element.find("Objects")
    if objects_element is not None:
        check = types_element is not None
        for child in objects_element:
            if child.tag != "Object":
                continue
            if memo is None:
                coe_object = parse_object(child, types, check)
            else:
                object_key = (table_id, element_key(child))
                coe_object = memo.objects.get(object_key)
                if coe_object is None:
                    coe_object = parse_object(child, types, check)
                    memo.objects[object_key] = coe_object
            objects.setdefault(coe_object.index, coe_object)
    return dict(types), objects
