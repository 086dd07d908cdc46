"""Sum commands on the device port: per-item results, the 500-item limit,
TwinCAT's refusal of sum-write there, and pyads' parsing of the answers."""

from __future__ import annotations

import ctypes
import struct
from typing import Any

import pyads
import pyads.connection
import pyads.pyads_ex
import pytest
from pyads.pyads_ex import ADSError
from pyads.structs import SAdsSymbolEntry

from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ads.sums import (
    SumReadItem,
    SumReadRequest,
    SumReadResponse,
    SumReadWriteItem,
    SumReadWriteRequest,
    SumReadWriteResponse,
    SumWriteItem,
    SumWriteRequest,
    SumWriteResponse,
)
from fastcs_ethercat.ads.symbols import AdsSymbolEntry
from fastcs_ethercat.sim.probe import SimProbe
from fastcs_ethercat.twincat.target import SimTarget
from tests.test_sim_model_support import (
    EL1014,
    EL2024,
    EL3104_COMPACT,
    EL3104_STANDARD,
    EL4134,
    demo_target,
    device,
    handle_of,
    info_by_name,
    target_from_text,
)

COMPACT = [f"{EL3104_COMPACT}.AI Compact Channel {n}" for n in range(1, 5)]


def sum_read(
    probe: SimProbe, items: list[SumReadItem]
) -> tuple[int, SumReadResponse | None]:
    request = SumReadRequest(tuple(items))
    answer = probe.read_write(
        IndexGroup.SUMUP_READ, len(items), request.read_length, request.encode()
    )
    if answer.result:
        return answer.result, None
    assert len(answer.data) == request.read_length
    return 0, SumReadResponse.decode(answer.data, [i.length for i in items])


def entry(probe: SimProbe, name: str) -> AdsSymbolEntry:
    return AdsSymbolEntry.decode(info_by_name(probe, name).data)


def test_sum_read_gives_values_and_per_item_errors() -> None:
    target = demo_target()
    probe = device(target)
    for position, name in enumerate(COMPACT):
        target.set_symbol_value(name, 100 * (position + 1))
    entries = [entry(probe, name) for name in COMPACT]
    items = [SumReadItem(e.index_group, e.index_offset, e.size) for e in entries]
    items.insert(2, SumReadItem(0x1234, 0, 2))  # unknown group
    items.append(SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, 999_999, 2))  # no handle
    result, answer = sum_read(probe, items)
    assert result == 0 and answer is not None
    assert answer.results == (
        0,
        0,
        AdsReturnCode.DEVICE_INVALID_GROUP,
        0,
        0,
        AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND,
    )
    values = [struct.unpack("<h", d)[0] for d in answer.data]
    assert values == [100, 200, 0, 300, 400, 0]


def test_sum_read_of_bits_and_by_handle() -> None:
    target = demo_target()
    probe = device(target)
    target.set_symbol_value(f"{EL1014}.Channel 2", True)
    target.set_symbol_value(f"{EL1014}.Channel 3", False)
    bits = [entry(probe, f"{EL1014}.Channel {n}") for n in (2, 3)]
    handle = handle_of(probe, f"{EL3104_STANDARD}.AI Standard Channel 4.Value")
    target.set_symbol_value(f"{EL3104_STANDARD}.AI Standard Channel 4.Value", -7)
    items = [SumReadItem(b.index_group, b.index_offset, 1) for b in bits]
    items.append(SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, handle, 2))
    _, answer = sum_read(probe, items)
    assert answer is not None
    assert answer.data == (b"\x01", b"\x00", struct.pack("<h", -7))


def test_a_sum_read_refuses_past_the_image_end_like_a_plain_read() -> None:
    """Each sub-read of a sum read answers what the same read alone answers:
    the bit just past the input image as well as bytes past it."""
    target = demo_target()
    probe = device(target)
    size = target.devices[0].layout.input_size
    reads = [
        (IndexGroup.IO_IMAGE_RW_INPUT_BITS, 8 * size, 1),
        (IndexGroup.IO_IMAGE_RW_INPUT_BITS, 8 * size + 9, 1),
        (IndexGroup.IO_IMAGE_RW_INPUT_BYTES, size, 1),
        (IndexGroup.IO_IMAGE_RW_INPUT_BYTES, size + 1, 1),
    ]
    _, answer = sum_read(probe, [SumReadItem(*read) for read in reads])

    assert answer is not None
    assert list(answer.results) == [probe.read(*read).result for read in reads]
    assert all(answer.results)


def test_more_than_500_items_are_refused_whole() -> None:
    probe = device(demo_target())
    first = entry(probe, COMPACT[0])
    item = SumReadItem(first.index_group, first.index_offset, 2)
    result, answer = sum_read(probe, [item] * 500)
    assert result == 0 and answer is not None and len(answer.results) == 500
    result, answer = sum_read(probe, [item] * 501)
    assert (result, answer) == (AdsReturnCode.DEVICE_INVALID_SIZE, None)


def test_the_limit_comes_from_the_chain() -> None:
    target = target_from_text(
        "system: {max_sum_items: 3}\n"
        "masters:\n- slaves: [{type: EL3104, pdo_group: Compact}]\n"
    )
    probe = device(target)
    first = entry(probe, "Term 1 (EL3104).AI Compact Channel 1")
    item = SumReadItem(first.index_group, first.index_offset, 2)
    assert sum_read(probe, [item] * 3)[0] == 0
    assert sum_read(probe, [item] * 4)[0] == AdsReturnCode.DEVICE_INVALID_SIZE


def test_sum_read_needs_room_for_its_answer() -> None:
    probe = device(demo_target())
    first = entry(probe, COMPACT[0])
    request = SumReadRequest((SumReadItem(first.index_group, first.index_offset, 2),))
    short = probe.read_write(
        IndexGroup.SUMUP_READ, 1, request.read_length - 1, request.encode()
    )
    assert short.result == AdsReturnCode.DEVICE_INVALID_SIZE
    broken = probe.read_write(IndexGroup.SUMUP_READ, 2, 100, request.encode())
    assert broken.result == AdsReturnCode.DEVICE_INVALID_SIZE


def test_sum_write_is_not_served_on_the_device_port() -> None:
    """A real TwinCAT answers 0x701 here (pyads issue #456)."""
    probe = device(demo_target())
    output = entry(probe, f"{EL4134}.AO Output Channel 1")
    request = SumWriteRequest(
        (SumWriteItem(output.index_group, output.index_offset, struct.pack("<h", 5)),)
    )
    answer = probe.read_write(
        IndexGroup.SUMUP_WRITE, 1, request.read_length, request.encode()
    )
    assert answer.result == AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED


def test_sum_write_with_per_item_errors_when_enabled() -> None:
    target = target_from_text(
        """
system: {sum_write_on_device_port: true}
masters:
- slaves: [{type: EL4134}, {type: EL2024}]
"""
    )
    probe = device(target)
    first = entry(probe, "Term 1 (EL4134).AO Output Channel 1")
    bit = entry(probe, "Term 2 (EL2024).Channel 4")
    request = SumWriteRequest(
        (
            SumWriteItem(
                first.index_group, first.index_offset, struct.pack("<h", -321)
            ),
            SumWriteItem(0x1234, 0, b"\0"),
            SumWriteItem(bit.index_group, bit.index_offset, b"\x01"),
            SumWriteItem(IndexGroup.SYM_VALUE_BY_HANDLE, 424242, b"\0\0"),
        )
    )
    answer = probe.read_write(
        IndexGroup.SUMUP_WRITE, 4, request.read_length, request.encode()
    )
    assert answer.result == 0
    assert SumWriteResponse.decode(answer.data, 4).results == (
        0,
        AdsReturnCode.DEVICE_INVALID_GROUP,
        0,
        AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND,
    )
    assert target.get_symbol_value("Term 1 (EL4134).AO Output Channel 1") == -321
    assert target.get_symbol_value("Term 2 (EL2024).Channel 4") is True


def test_sum_read_write_resolves_many_names_at_once() -> None:
    probe = device(demo_target())
    names = [*COMPACT[:2], "no such symbol", f"{EL2024}.Channel 1"]
    request = SumReadWriteRequest(
        tuple(
            SumReadWriteItem(IndexGroup.SYM_INFO_BY_NAME_EX, 0, 512, n.encode() + b"\0")
            for n in names
        )
    )
    answer = probe.read_write(
        IndexGroup.SUMUP_READ_WRITE, len(names), request.read_length, request.encode()
    )
    assert answer.result == 0
    decoded = SumReadWriteResponse.decode(answer.data, len(names))
    assert decoded.results[2] == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    assert decoded.data[2] == b""
    found = [AdsSymbolEntry.decode(d) for i, d in enumerate(decoded.data) if i != 2]
    assert [e.name for e in found] == [*COMPACT[:2], f"{EL2024}.Channel 1"]
    handles = SumReadWriteRequest(
        tuple(
            SumReadWriteItem(IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, n.encode())
            for n in COMPACT
        )
    )
    made = probe.read_write(
        IndexGroup.SUMUP_READ_WRITE, 4, handles.read_length, handles.encode()
    )
    numbers = [
        struct.unpack("<I", d)[0]
        for d in SumReadWriteResponse.decode(made.data, 4).data
    ]
    assert len(set(numbers)) == 4


def test_nested_sum_commands_are_refused_per_item() -> None:
    probe = device(demo_target())
    _, answer = sum_read(probe, [SumReadItem(IndexGroup.SUMUP_READ, 0, 4)])
    assert answer is not None
    assert answer.results == (AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED,)


# -- pyads parses the answers ---------------------------------------------------------


@pytest.fixture
def pyads_on_probe(
    monkeypatch: pytest.MonkeyPatch,
) -> tuple[SimTarget, pyads.Connection]:
    """A pyads Connection whose DLL calls go to an in-process probe, so its
    own symbol-info caching, 500-item chunking and sum-read parsing run."""
    target = demo_target()
    probe = device(target)
    sum_requests: list[int] = []

    def symbol_info(port: int, address: Any, name: str) -> SAdsSymbolEntry:
        answer = info_by_name(probe, name, ctypes.sizeof(SAdsSymbolEntry))
        if answer.result:
            raise ADSError(answer.result)
        size = ctypes.sizeof(SAdsSymbolEntry)
        return SAdsSymbolEntry.from_buffer_copy(answer.data.ljust(size, b"\0"))

    def sum_read_bytes(
        port: int, address: Any, infos: list[tuple[int, int, int]]
    ) -> bytes:
        request = SumReadRequest(tuple(SumReadItem(*info) for info in infos))
        sum_requests.append(len(infos))
        answer = probe.read_write(
            IndexGroup.SUMUP_READ, len(infos), request.read_length, request.encode()
        )
        if answer.result:
            raise ADSError(answer.result)
        return answer.data

    monkeypatch.setattr(pyads.connection, "adsGetSymbolInfo", symbol_info)
    monkeypatch.setattr(pyads.pyads_ex, "adsSumReadBytes", sum_read_bytes)
    connection = pyads.Connection("127.0.0.1.1.1", 27905)
    connection._port = 1
    connection.sum_requests = sum_requests  # type: ignore[attr-defined]
    return target, connection


def test_pyads_read_list_by_name_parses_our_sum_read(
    pyads_on_probe: tuple[SimTarget, pyads.Connection],
) -> None:
    target, connection = pyads_on_probe
    for position, name in enumerate(COMPACT):
        target.set_symbol_value(name, -1000 * position)
    target.set_symbol_value(f"{EL1014}.Channel 4", True)
    names = [*COMPACT, f"{EL1014}.Channel 4", f"{EL1014}.Channel 4.Input"]
    values = connection.read_list_by_name(names)
    assert values == {
        COMPACT[0]: 0,
        COMPACT[1]: -1000,
        COMPACT[2]: -2000,
        COMPACT[3]: -3000,
        f"{EL1014}.Channel 4": True,
        f"{EL1014}.Channel 4.Input": True,
    }


def test_pyads_splits_at_500_and_we_answer_every_chunk(
    pyads_on_probe: tuple[SimTarget, pyads.Connection],
) -> None:
    target, connection = pyads_on_probe
    names = [
        f"{EL3104_STANDARD}.AI Standard Channel {n}.Status.{bit}"
        for n in range(1, 5)
        for bit in ("Underrange", "Overrange", "Error", "TxPDO State")
    ] + [f"{EL3104_STANDARD}.AI Standard Channel {n}.Value" for n in range(1, 5)]
    many = (names * 40)[:620]
    values = connection.read_list_by_name(many)
    assert connection.sum_requests == [500, 120]  # type: ignore[attr-defined]
    for n in range(1, 5):
        name = f"{EL3104_STANDARD}.AI Standard Channel {n}.Value"
        assert values[name] == target.get_symbol_value(name)
