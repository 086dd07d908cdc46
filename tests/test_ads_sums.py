"""Sum commands: layouts by hand, round trips, and pyads' own sum parsing."""

from __future__ import annotations

import contextlib
import ctypes
import struct
from typing import Any

import numpy as np
import pyads.pyads_ex as pyads_ex
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pyads.structs import AmsAddr, SAdsSymbolEntry

from fastcs_ethercat.ads.commands import AddDeviceNotificationRequest
from fastcs_ethercat.ads.constants import (
    MAX_SUM_SUB_COMMANDS,
    AdsDataType,
    AdsReturnCode,
    IndexGroup,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.sums import (
    SumAddNotificationsRequest,
    SumAddNotificationsResponse,
    SumDeleteNotificationsRequest,
    SumDeleteNotificationsResponse,
    SumReadItem,
    SumReadLayout,
    SumReadRequest,
    SumReadResponse,
    SumReadWriteItem,
    SumReadWriteRequest,
    SumReadWriteResponse,
    SumWriteItem,
    SumWriteRequest,
    SumWriteResponse,
    chunked,
)
from fastcs_ethercat.ads.symbols import AdsSymbolEntry

u32 = st.integers(0, 0xFFFF_FFFF)
blobs = st.binary(max_size=12)


def test_sum_read_layout_by_hand() -> None:
    request = SumReadRequest((SumReadItem(0xF020, 26, 4), SumReadItem(0xF021, 320, 1)))
    assert request.encode() == struct.pack("<6I", 0xF020, 26, 4, 0xF021, 320, 1)
    rw = request.to_read_write()
    assert (rw.index_group, rw.index_offset, rw.read_length) == (0xF080, 2, 8 + 5)
    response = SumReadResponse.for_items(
        request.items,
        [(0, b"\x01\x00\x02\x00"), (AdsReturnCode.DEVICE_INVALID_OFFSET, b"")],
    )
    raw = response.encode()
    assert raw == struct.pack("<II", 0, 0x703) + b"\x01\x00\x02\x00" + b"\x00"
    assert SumReadResponse.decode(raw, [4, 1]) == response


def test_sum_read_layout_views_a_whole_answer() -> None:
    raw = struct.pack("<II", 0, 0x710) + struct.pack("<hH", -5, 7) + b"\x01"
    layout = SumReadLayout([4, 1])
    view = np.frombuffer(raw, dtype=layout.dtype([("ai", "<i2", 8), ("bit", "u1", 12)]))
    assert layout.data_offsets.tolist() == [8, 12]
    assert layout.size == len(raw)
    assert view[0]["results"].tolist() == [0, 0x710]
    assert (view[0]["ai"], view[0]["bit"]) == (-5, 1)
    assert layout.split(raw) == ((0, 0x710), (raw[8:12], b"\x01"))
    assert SumReadLayout([]).data_offsets.tolist() == []
    with pytest.raises(AdsCodecError):
        layout.split(raw[:-1])


@given(st.lists(st.tuples(u32, u32, st.binary(max_size=8), u32), max_size=6))
def test_sum_read_round_trip(raw_items: list[tuple[int, int, bytes, int]]) -> None:
    items = tuple(SumReadItem(g, o, len(d)) for g, o, d, _ in raw_items)
    request = SumReadRequest(items)
    assert SumReadRequest.decode(request.encode(), len(items)) == request
    response = SumReadResponse.for_items(items, [(r, d) for _, _, d, r in raw_items])
    assert (
        SumReadResponse.decode(response.encode(), [i.length for i in items]) == response
    )


@given(st.lists(st.builds(SumWriteItem, u32, u32, blobs), max_size=6), st.data())
def test_sum_write_round_trip(items: list[SumWriteItem], data: st.DataObject) -> None:
    request = SumWriteRequest(tuple(items))
    assert SumWriteRequest.decode(request.encode(), len(items)) == request
    response = SumWriteResponse(
        tuple(data.draw(st.lists(u32, min_size=len(items), max_size=len(items))))
    )
    assert SumWriteResponse.decode(response.encode(), len(items)) == response


@given(
    st.lists(st.builds(SumReadWriteItem, u32, u32, u32, blobs), max_size=6), st.data()
)
def test_sum_read_write_round_trip(
    items: list[SumReadWriteItem], data: st.DataObject
) -> None:
    request = SumReadWriteRequest(tuple(items))
    assert SumReadWriteRequest.decode(request.encode(), len(items)) == request
    n = len(items)
    response = SumReadWriteResponse(
        tuple(data.draw(st.lists(u32, min_size=n, max_size=n))),
        tuple(data.draw(st.lists(blobs, min_size=n, max_size=n))),
    )
    assert SumReadWriteResponse.decode(response.encode(), n) == response


def test_sum_read_write_layout_by_hand() -> None:
    request = SumReadWriteRequest((SumReadWriteItem(0xF009, 0, 798, b"A.b\0"),))
    assert request.encode() == struct.pack("<4I", 0xF009, 0, 798, 4) + b"A.b\0"
    assert request.to_read_write().index_group == 0xF082
    response = SumReadWriteResponse((0, 0x710), (b"xyz", b""))
    assert response.encode() == struct.pack("<4I", 0, 3, 0x710, 0) + b"xyz"


def test_bulk_notifications_round_trip() -> None:
    add = SumAddNotificationsRequest(
        (AddDeviceNotificationRequest(0xF021, 8, 1, 3, 0, 100_000),) * 2
    )
    assert len(add.encode()) == 80
    assert SumAddNotificationsRequest.decode(add.encode(), 2) == add
    added = SumAddNotificationsResponse((0, 0x702), (5, 0))
    assert SumAddNotificationsResponse.decode(added.encode(), 2) == added
    delete = SumDeleteNotificationsRequest((5, 6))
    assert SumDeleteNotificationsRequest.decode(delete.encode(), 2) == delete
    deleted = SumDeleteNotificationsResponse((0, 0x714))
    assert SumDeleteNotificationsResponse.decode(deleted.encode(), 2) == deleted


@pytest.mark.parametrize(
    ("decode", "raw", "count"),
    [
        (SumReadRequest.decode, b"\0" * 11, 1),
        (SumReadRequest.decode, b"\0" * 13, 1),
        (SumWriteRequest.decode, struct.pack("<3I", 1, 2, 4) + b"\0\0", 1),
        (SumReadWriteRequest.decode, b"\0" * 15, 1),
        (SumWriteResponse.decode, b"\0" * 7, 2),
        (SumReadWriteResponse.decode, struct.pack("<2I", 0, 9) + b"\0", 1),
        (SumAddNotificationsRequest.decode, b"\0" * 39, 1),
        (SumReadRequest.decode, b"", 2**30),
    ],
)
def test_wrong_sizes_are_parameter_size_errors(
    decode: Any, raw: bytes, count: int
) -> None:
    with pytest.raises(AdsCodecError) as caught:
        decode(raw, count)
    assert caught.value.return_code == AdsReturnCode.DEVICE_INVALID_SIZE


def test_for_items_rejects_oversized_data() -> None:
    with pytest.raises(AdsCodecError):
        SumReadResponse.for_items([SumReadItem(1, 2, 1)], [(0, b"ab")])


def test_chunks_of_500() -> None:
    assert MAX_SUM_SUB_COMMANDS == 500
    assert [len(c) for c in chunked(list(range(1201)))] == [500, 500, 201]


@given(st.binary(max_size=64), st.integers(0, 10))
def test_decoders_only_raise_codec_errors(raw: bytes, count: int) -> None:
    for decode in (
        SumReadRequest.decode,
        SumWriteRequest.decode,
        SumReadWriteRequest.decode,
        SumWriteResponse.decode,
        SumReadWriteResponse.decode,
        SumAddNotificationsRequest.decode,
        SumAddNotificationsResponse.decode,
        SumDeleteNotificationsRequest.decode,
        SumDeleteNotificationsResponse.decode,
    ):
        with contextlib.suppress(AdsCodecError):
            decode(raw, count)
    with contextlib.suppress(AdsCodecError):
        SumReadResponse.decode(raw, [count] * count)


def _pyads_symbol(entry: AdsSymbolEntry) -> SAdsSymbolEntry:
    raw = entry.encode().ljust(ctypes.sizeof(SAdsSymbolEntry), b"\0")
    return SAdsSymbolEntry.from_buffer_copy(raw)


def test_pyads_sum_read_parses_our_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    """pyads' adsSumRead walks our 0xF080 answer: per-item results, data at
    requested sizes even after a failed item."""
    symbols = {
        "a": AdsSymbolEntry("a", 0xF020, 0, 2, AdsDataType.INT16, "INT"),
        "b": AdsSymbolEntry("b", 0xF020, 2, 4, AdsDataType.UINT32, "UDINT"),
        "c": AdsSymbolEntry("c", 0xF020, 6, 8, AdsDataType.REAL64, "LREAL"),
    }
    items = [
        SumReadItem(s.index_group, s.index_offset, s.size) for s in symbols.values()
    ]
    answer = SumReadResponse.for_items(
        items,
        [
            (0, struct.pack("<h", -1234)),
            (AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND, b""),
            (0, struct.pack("<d", 2.5)),
        ],
    ).encode()
    seen: list[Any] = []

    def fake_sum_read_bytes(port: int, address: AmsAddr, data_symbols: Any) -> bytes:
        seen.extend(data_symbols)
        return answer

    monkeypatch.setattr(pyads_ex, "adsSumReadBytes", fake_sum_read_bytes)
    result = pyads_ex.adsSumRead(
        1,
        AmsAddr("127.0.0.1.1.1", 27905),
        list(symbols),
        {name: _pyads_symbol(entry) for name, entry in symbols.items()},
        [],
    )
    assert seen == [(i.index_group, i.index_offset, i.length) for i in items]
    assert result["a"] == -1234
    assert result["b"] == "symbol not found"
    assert result["c"] == 2.5


def test_pyads_sum_write_request_decodes_with_ours(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """pyads' adsSumWrite builds a 0xF081 request our decoder reads; our
    answer's per-item results come back as pyads' error strings."""
    symbols = {
        "a": AdsSymbolEntry("a", 0xF030, 0, 2, AdsDataType.INT16, "INT"),
        "b": AdsSymbolEntry("b", 0xF030, 2, 1, AdsDataType.UINT8, "USINT"),
    }
    captured: dict[str, Any] = {}

    def fake_read_write(
        port: int,
        address: AmsAddr,
        index_group: int,
        index_offset: int,
        read_type: Any,
        value: Any,
        write_type: Any,
        **_: Any,
    ) -> bytes:
        captured["group"], captured["count"] = index_group, index_offset
        captured["request"] = SumWriteRequest.decode(bytes(value), index_offset)
        return SumWriteResponse((0, AdsReturnCode.DEVICE_INVALID_ACCESS)).encode()

    monkeypatch.setattr(pyads_ex, "adsSyncReadWriteReqEx2", fake_read_write)
    result = pyads_ex.adsSumWrite(
        1,
        AmsAddr("127.0.0.1.1.1", 27905),
        {"a": -2, "b": 7},
        {name: _pyads_symbol(entry) for name, entry in symbols.items()},
        [],
    )
    assert captured["group"] == IndexGroup.SUMUP_WRITE
    assert captured["request"] == SumWriteRequest(
        (
            SumWriteItem(0xF030, 0, struct.pack("<h", -2)),
            SumWriteItem(0xF030, 2, b"\x07"),
        )
    )
    assert result == {"a": "no error", "b": "reading/writing not permitted"}
