"""Data-type entries: hand-written layout, recursion, round trips, layouts."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fastcs_ethercat.ads.constants import AdsDataType, DataTypeFlag
from fastcs_ethercat.ads.datatypes import (
    AdsDataTypeEntry,
    ArrayDimension,
    MemberLayout,
    decode_data_type_table,
    encode_data_type_table,
    walk_members,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from tests.ads_codec import MemberSpec, layout_structure

AI_TYPE = layout_structure(
    "AI Standard Channel 1_TYPE",
    [
        MemberSpec("Status", "UINT", AdsDataType.UINT16, 2),
        MemberSpec("Value", "INT", AdsDataType.INT16, 2),
    ],
)

texts = st.text(
    alphabet=st.characters(codec="cp1252", exclude_characters="\0"), max_size=12
)
u32 = st.integers(0, 0xFFFF_FFFF)
leaves = st.builds(
    AdsDataTypeEntry,
    name=texts,
    type_name=texts,
    size=u32,
    data_type=st.sampled_from(list(AdsDataType)),
    flags=u32,
    offset=u32,
    comment=texts,
    array_dimensions=st.lists(
        st.builds(ArrayDimension, st.integers(-(2**31), 2**31 - 1), u32), max_size=2
    ).map(tuple),
    hash_value=u32,
    type_hash_value=u32,
)
entries = st.recursive(
    leaves,
    lambda children: st.builds(
        AdsDataTypeEntry,
        name=texts,
        type_name=texts,
        size=u32,
        sub_items=st.lists(children, max_size=3).map(tuple),
    ),
    max_leaves=8,
)


def _without_padding(entry: AdsDataTypeEntry) -> AdsDataTypeEntry:
    """The entry as it was before encoding padded it (extra is padding only)."""
    assert entry.extra.strip(b"\0") == b""
    return AdsDataTypeEntry(
        entry.name,
        entry.type_name,
        entry.size,
        entry.data_type,
        entry.flags,
        entry.offset,
        entry.comment,
        entry.array_dimensions,
        tuple(_without_padding(item) for item in entry.sub_items),
        entry.version,
        entry.hash_value,
        entry.type_hash_value,
    )


def test_layout_written_out_by_hand() -> None:
    member = AdsDataTypeEntry(
        "V", "INT", 2, AdsDataType.INT16, DataTypeFlag.DATA_ITEM, 2
    )
    parent = AdsDataTypeEntry(
        "T", "", 4, array_dimensions=(ArrayDimension(1, 3),), sub_items=(member,)
    )
    member_raw = (
        # 42-byte header + "V\0INT\0" + empty comment "\0" = 49, padded to 56
        struct.pack("<8I", 56, 1, 0, 0, 2, 2, AdsDataType.INT16, DataTypeFlag.DATA_ITEM)
        + struct.pack("<5H", 1, 3, 0, 0, 0)
        + b"V\0INT\0\0"
        + b"\0" * 7
    )
    header_and_strings = (
        struct.pack(
            "<8I", 0, 1, 0, 0, 4, 0, AdsDataType.BIGTYPE, DataTypeFlag.DATA_TYPE
        )
        + struct.pack("<5H", 1, 0, 0, 1, 1)
        + b"T\0\0\0"
    )
    dims = struct.pack("<iI", 1, 3)
    body_length = len(header_and_strings) + len(dims) + len(member_raw)  # 46+8+56
    padded = -(-body_length // 8) * 8
    expected = (
        struct.pack("<I", padded)
        + header_and_strings[4:]
        + dims
        + member_raw
        + b"\0" * (padded - body_length)
    )
    assert member.encode() == member_raw
    assert parent.encode() == expected
    decoded = AdsDataTypeEntry.decode(expected)
    assert decoded.sub_items[0].name == "V"
    assert decoded.sub_items[0].offset == 2
    assert decoded.array_dimensions == (ArrayDimension(1, 3),)
    (dimension,) = decoded.array_dimensions
    assert dimension.lower_bound + dimension.element_count - 1 == 3  # ARRAY [1..3]


@given(entries)
def test_round_trip(entry: AdsDataTypeEntry) -> None:
    raw = entry.encode()
    decoded = AdsDataTypeEntry.decode(raw)
    assert _without_padding(decoded) == entry
    assert decoded.encode() == raw


@given(st.lists(entries, max_size=4))
def test_table_round_trip(table: list[AdsDataTypeEntry]) -> None:
    decoded = decode_data_type_table(encode_data_type_table(table))
    assert [_without_padding(e) for e in decoded] == table


def test_packed_structure_layout_of_an_analog_input() -> None:
    assert AI_TYPE.size == 4
    assert [(m.name, m.offset) for m in AI_TYPE.sub_items] == [
        ("Status", 0),
        ("Value", 2),
    ]
    assert walk_members(AI_TYPE) == [
        MemberLayout("Status", "UINT", AdsDataType.UINT16, 0, 2),
        MemberLayout("Value", "INT", AdsDataType.INT16, 2, 2),
    ]


def test_aligned_structure_layout() -> None:
    entry = layout_structure(
        "S",
        [
            MemberSpec("a", "BYTE", AdsDataType.UINT8, 1),
            MemberSpec("b", "DINT", AdsDataType.INT32, 4),
            MemberSpec("c", "INT", AdsDataType.INT16, 2),
        ],
        pack=8,
    )
    assert [m.offset for m in entry.sub_items] == [0, 4, 8]
    assert entry.size == 12


def test_nested_members_resolve_through_the_type_table() -> None:
    outer = layout_structure(
        "Outer",
        [
            MemberSpec("Head", "BYTE", AdsDataType.UINT8, 1),
            MemberSpec("AI", AI_TYPE.name, AdsDataType.BIGTYPE, 4),
        ],
    )
    members = walk_members(outer, {AI_TYPE.name: AI_TYPE})
    assert [(m.path, m.offset) for m in members] == [
        ("Head", 0),
        ("AI.Status", 1),
        ("AI.Value", 3),
    ]


def test_sub_item_running_past_its_parent_is_rejected() -> None:
    raw = bytearray(AI_TYPE.encode())
    first_sub = 42 + len(AI_TYPE.name) + 1 + 1 + 1
    struct.pack_into("<I", raw, first_sub, len(raw))
    with pytest.raises(AdsCodecError):
        AdsDataTypeEntry.decode(bytes(raw))


@given(st.binary(max_size=300))
def test_decoder_only_raises_codec_errors(raw: bytes) -> None:
    with contextlib.suppress(AdsCodecError):
        decode_data_type_table(raw)
