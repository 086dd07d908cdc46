"""Symbol entries and upload info: layout by hand, round trips, pyads parsing."""

from __future__ import annotations

import contextlib
import ctypes
import struct
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pyads import Connection
from pyads.structs import SAdsSymbolEntry

from fastcs_ethercat.ads.constants import AdsDataType, IndexGroup, SymbolFlag
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.symbols import (
    AdsSymbolEntry,
    SymbolUploadInfo,
    SymbolUploadInfo2,
    decode_symbol_table,
    encode_symbol_name,
    encode_symbol_table,
)
from tests.ads_codec import decode_symbol_name

ANALOG = AdsSymbolEntry(
    name="Term 2 (EL3104).AI Standard Channel 1",
    index_group=IndexGroup.IO_IMAGE_RW_INPUT_BYTES,
    index_offset=26,
    size=4,
    data_type=AdsDataType.BIGTYPE,
    type_name="AI Standard Channel 1_TYPE",
    comment="",
)
DIGITAL = AdsSymbolEntry(
    name="Term 4 (EL1014).Channel 1.Input",
    index_group=IndexGroup.IO_IMAGE_RW_INPUT_BITS,
    index_offset=8 * 40,
    size=1,
    data_type=AdsDataType.BIT,
    type_name="BIT",
    comment="Input",
    flags=SymbolFlag.BIT_VALUE,
)

texts = st.text(
    alphabet=st.characters(codec="cp1252", exclude_characters="\0"), max_size=40
)
u32 = st.integers(0, 0xFFFF_FFFF)
entries = st.builds(
    AdsSymbolEntry,
    name=texts,
    index_group=u32,
    index_offset=u32,
    size=u32,
    data_type=st.sampled_from(list(AdsDataType)),
    type_name=texts,
    comment=texts,
    flags=u32,
)


def test_layout_written_out_by_hand() -> None:
    entry = AdsSymbolEntry("ab", 0xF020, 2, 2, AdsDataType.INT16, "INT", "c")
    expected = (
        # entry length 30 + (2+1) + (3+1) + (1+1) = 39, padded to 40
        struct.pack("<IIIIII", 40, 0xF020, 2, 2, AdsDataType.INT16, 0)
        + struct.pack("<HHH", 2, 3, 1)  # name, type, comment lengths at bytes 24..30
        + b"ab\0INT\0c\0"
        + b"\0"  # padding
    )
    raw = entry.encode()
    assert raw == expected
    assert len(raw) == 40
    assert raw[30:33] == b"ab\0"
    assert AdsSymbolEntry.decode(raw) == AdsSymbolEntry(
        "ab", 0xF020, 2, 2, AdsDataType.INT16, "INT", "c", extra=b"\0"
    )


def test_decoded_entry_reencodes_byte_exact() -> None:
    guid = bytes(range(16))
    entry = AdsSymbolEntry(
        "GVL.counter", 0x4040, 385000, 2, 18, "UINT", " Counter (in pulses)", 8, guid
    )
    raw = entry.encode()
    assert len(raw) == 88  # pyads' docstring example of a real entry
    assert AdsSymbolEntry.decode(raw).encode() == raw


@given(entries)
def test_round_trip(entry: AdsSymbolEntry) -> None:
    decoded = AdsSymbolEntry.decode(entry.encode())
    assert decoded.extra.strip(b"\0") == b""
    assert decoded == AdsSymbolEntry(
        entry.name,
        entry.index_group,
        entry.index_offset,
        entry.size,
        entry.data_type,
        entry.type_name,
        entry.comment,
        entry.flags,
        decoded.extra,
    )


@given(st.lists(entries, max_size=6))
def test_table_round_trip(table: list[AdsSymbolEntry]) -> None:
    raw = encode_symbol_table(table)
    names = [e.name for e in decode_symbol_table(raw)]
    assert names == [e.name for e in table]
    assert [e.name for e in decode_symbol_table(raw, len(table))] == names


def test_pyads_ctypes_struct_reads_our_entry() -> None:
    """pyads.structs.SAdsSymbolEntry (what 0xF009 answers land in) agrees."""
    raw = DIGITAL.encode()
    buffer = raw.ljust(ctypes.sizeof(SAdsSymbolEntry), b"\0")
    parsed = SAdsSymbolEntry.from_buffer_copy(buffer)
    assert parsed.entryLength == len(raw)
    assert parsed.iGroup == DIGITAL.index_group
    assert parsed.iOffs == DIGITAL.index_offset
    assert parsed.size == DIGITAL.size
    assert parsed.dataType == AdsDataType.BIT
    assert parsed.flags == SymbolFlag.BIT_VALUE
    assert parsed.name == DIGITAL.name
    assert parsed.symbol_type == "BIT"
    assert parsed.comment == "Input"


def test_pyads_get_all_symbols_parses_our_upload() -> None:
    """Run pyads' own Connection.get_all_symbols over our 0xF00F/0xF00B bytes."""
    table = [ANALOG, DIGITAL]
    raw_table = encode_symbol_table(table)
    info = SymbolUploadInfo2(len(table), len(raw_table), 0, 0, 0, 0).encode()
    reads: list[tuple[int, int]] = []

    def fake_read(index_group: int, index_offset: int, *_: Any, **__: Any) -> bytes:
        reads.append((index_group, index_offset))
        if index_group == IndexGroup.SYM_UPLOAD_INFO_2:
            return info.ljust(1024, b"\0")  # pyads reads with a 1024-byte buffer
        assert index_group == IndexGroup.SYM_UPLOAD
        return raw_table

    connection = Connection("127.0.0.1.1.1", 27905)
    connection._port = 1  # pretend open; no AdsLib call happens below
    connection.read = fake_read  # type: ignore[method-assign]
    symbols = connection.get_all_symbols()
    assert reads == [(IndexGroup.SYM_UPLOAD_INFO_2, 0), (IndexGroup.SYM_UPLOAD, 0)]
    assert [
        (s.name, s.index_group, s.index_offset, s.symbol_type) for s in symbols
    ] == [(e.name, e.index_group, e.index_offset, e.type_name) for e in table]
    assert symbols[1].comment == "Input"


def test_upload_infos() -> None:
    assert SymbolUploadInfo(3, 300).encode() == struct.pack("<II", 3, 300)
    assert SymbolUploadInfo.decode(struct.pack("<II", 3, 300)) == SymbolUploadInfo(
        3, 300
    )
    info = SymbolUploadInfo2(377, 50000, 40, 9000, 0, 0)
    raw = info.encode()
    assert raw == struct.pack("<6I", 377, 50000, 40, 9000, 0, 0)
    assert SymbolUploadInfo2.decode(raw) == info
    assert SymbolUploadInfo2.decode(raw.ljust(1024, b"\0")) == info
    with pytest.raises(AdsCodecError):
        SymbolUploadInfo2.decode(raw[:23])
    with pytest.raises(AdsCodecError):
        SymbolUploadInfo.decode(raw)


@pytest.mark.parametrize(
    "mutate",
    [
        lambda raw: raw[:29],  # header cut
        lambda raw: struct.pack("<I", 31) + raw[4:],  # entry shorter than strings
        lambda raw: struct.pack("<I", len(raw) + 8) + raw[4:],  # runs past the end
        lambda raw: raw[:32] + b"X" + raw[33:],  # name's NUL replaced
    ],
)
def test_malformed_entries(mutate: Any) -> None:
    raw = AdsSymbolEntry("ab", 1, 2, 2, AdsDataType.INT16, "INT").encode()
    with pytest.raises(AdsCodecError):
        AdsSymbolEntry.decode(mutate(raw))


def test_table_count_beyond_data_is_an_error() -> None:
    raw = encode_symbol_table([ANALOG])
    with pytest.raises(AdsCodecError):
        decode_symbol_table(raw, count=2)


@given(st.binary(max_size=200))
def test_table_decoder_only_raises_codec_errors(raw: bytes) -> None:
    with contextlib.suppress(AdsCodecError):
        decode_symbol_table(raw)


def test_by_name_request_data() -> None:
    """pyads writes the name plus a NUL (write length = len(name) + 1)."""
    assert encode_symbol_name("Term 1 (EK1100).ID") == b"Term 1 (EK1100).ID\0"
    assert decode_symbol_name(b"Term 1 (EK1100).ID\0") == "Term 1 (EK1100).ID"
    assert decode_symbol_name(b"no terminator") == "no terminator"
