"""The simulator's sum read fast path (precompiled plans) answers exactly what
the general path answers: bytes, single bits, both images, errors, and after
the images change."""

from __future__ import annotations

import random

from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ads.sums import SumReadItem, SumReadRequest
from fastcs_ethercat.twincat.layout import AREAS
from fastcs_ethercat.twincat.services import DevicePort, SumReadPlans
from fastcs_ethercat.twincat.target import SimTarget
from tests.test_sim_model_support import demo_target, device


def _answer(port: DevicePort, items: list[SumReadItem], length: int = 0) -> tuple:
    request = SumReadRequest(tuple(items))
    return port.read_write(
        IndexGroup.SUMUP_READ,
        len(items),
        length or request.read_length,
        request.encode(),
    )


def _general(port: DevicePort, items: list[SumReadItem], length: int = 0) -> tuple:
    """The answer without any remembered plan (the general path)."""
    port.plans = SumReadPlans()
    answer = _answer(port, items, length)
    port.plans = SumReadPlans()
    return answer


def _port(target: SimTarget) -> DevicePort:
    probe = device(target)
    port = target._ports[probe.address]  # the port under test
    assert isinstance(port, DevicePort)
    return port


def _mixed_items(target: SimTarget, count: int, seed: int) -> list[SumReadItem]:
    """Symbols of the symbol table plus single bits and raw slices of both
    images, shuffled."""
    draw = random.Random(seed)
    table = target.devices[0].table
    image = target.devices[0].image
    items = [SumReadItem(s.index_group, s.index_offset, s.size) for s in table.symbols]
    for area in AREAS:
        size = len(image.buffer(area))
        for _ in range(20):
            items.append(SumReadItem(area.bit_group, draw.randrange(8 * size), 1))
            offset = draw.randrange(size)
            items.append(
                SumReadItem(area.byte_group, offset, draw.randint(0, size - offset))
            )
    draw.shuffle(items)
    return items[:count]


def test_the_fast_path_answers_like_the_general_path() -> None:
    target = demo_target()
    port = _port(target)
    items = _mixed_items(target, 500, seed=1)
    expected = _general(port, items)
    assert expected[0] == AdsReturnCode.NO_ERROR
    assert _answer(port, items) == expected  # learns the plan
    assert len(port.plans.plans) == 1
    assert _answer(port, items) == expected  # answered from the plan
    # New values in both images: the plan reads them, not a stale copy.
    for buffer in (port.dev.image.inputs, port.dev.image.outputs):
        buffer[:] = bytes(random.Random(2).randrange(256) for _ in buffer)
    assert _answer(port, items) == _general(port, items)
    target.tick(target.cycle_s * 7)
    assert _answer(port, items) == _general(port, items)


def test_requests_the_plan_cannot_take_keep_their_errors() -> None:
    target = demo_target()
    port = _port(target)
    inputs = len(port.dev.image.inputs)
    group = AREAS[0].byte_group
    beyond = [SumReadItem(group, 0, 2), SumReadItem(group, inputs + 4, 2)]
    other = [SumReadItem(group, 0, 2), SumReadItem(IndexGroup.SYM_VERSION, 0, 1)]
    for items in (beyond, other):
        expected = _general(port, items)
        assert _answer(port, items) == expected
        assert _answer(port, items) == expected
    fine = [SumReadItem(group, 0, 2)]
    _answer(port, fine)
    short = _answer(port, fine, length=5)
    assert short[0] == AdsReturnCode.DEVICE_INVALID_SIZE
    wrong_count = port.read_write(
        IndexGroup.SUMUP_READ, 2, 100, SumReadRequest(tuple(fine)).encode()
    )
    assert wrong_count[0] == AdsReturnCode.DEVICE_INVALID_SIZE


def test_an_online_change_forgets_every_plan() -> None:
    target = demo_target()
    port = _port(target)
    items = _mixed_items(target, 100, seed=3)
    _answer(port, items)
    assert port.plans.plans
    target.online_change()
    fresh = _port(target)
    assert not fresh.plans.plans
    symbols = target.devices[0].table.symbols[:50]
    moved = [SumReadItem(s.index_group, s.index_offset, s.size) for s in symbols]
    assert _answer(fresh, moved) == _general(fresh, moved)


def _handles(port: DevicePort, names: list[str]) -> list[int]:
    handles = []
    for name in names:
        result, data = port.read_write(
            IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, name.encode("cp1252") + b"\0"
        )
        assert result == AdsReturnCode.NO_ERROR
        handles.append(int.from_bytes(data, "little"))
    return handles


def test_reads_by_handle_answer_like_the_general_path_while_valid() -> None:
    """Every symbol by its handle (bit symbols, structures, arrays; some read
    shorter and some longer than they are) from the plan, as the general
    path answers; an online change or a released handle is never answered
    from a plan (0x711 / 0x710 per item)."""
    target = demo_target()
    port = _port(target)
    symbols = target.devices[0].table.symbols
    handles = _handles(port, [s.name for s in symbols])
    lengths = [s.size + (n % 3) - 1 or 1 for n, s in enumerate(symbols)]
    items = [
        SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, h, n)
        for h, n in zip(handles, lengths, strict=True)
    ][:500]
    expected = _general(port, items)
    assert _answer(port, items) == expected
    assert port.plans.plans.get(SumReadRequest(tuple(items)).encode()) is not None
    target.tick(target.cycle_s * 3)
    assert _answer(port, items) == _general(port, items)

    release = port.write(
        IndexGroup.SYM_RELEASE_HANDLE, 0, handles[0].to_bytes(4, "little")
    )
    released = _answer(port, items)
    released_general = _general(port, items)
    target.online_change()
    changed = _answer(_port(target), items)

    assert release == AdsReturnCode.NO_ERROR
    assert released[1][:4] == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND.to_bytes(
        4, "little"
    )
    assert released == released_general
    results = [
        int.from_bytes(changed[1][4 * i : 4 * i + 4], "little")
        for i in range(len(items))
    ]
    assert results[0] == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND  # released
    assert set(results[1:]) == {AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID}
