"""The client against a target without sum commands (fault `no_sum_commands`):
the same answers from single requests, decided once per connection and said
once; and a short 0xF00F answer used for the fields it has.

Against the simulator's own model in process (`twincat.inprocess`): a target that
answers 0xF080-0xF082 with 0x701, as older TwinCAT 2, pcdshub's ads-async,
fastcs-catio's simulator and pyads' test server do.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import pytest

from fastcs_ethercat.ads import client as client_module
from fastcs_ethercat.ads.client import AdsClient
from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup, device_port
from fastcs_ethercat.ads.frames import AmsPacket
from fastcs_ethercat.ads.sums import SumReadItem, SumReadResponse
from fastcs_ethercat.sim.counters import RequestCounters
from fastcs_ethercat.twincat.inprocess import sim_clients
from fastcs_ethercat.twincat.target import SimTarget
from tests.test_sim_model_support import EL3104_COMPACT, demo_target

SYMBOLS = [f"{EL3104_COMPACT}.AI Compact Channel {n}" for n in range(1, 5)]
MISSING = "Term 99 (EL9999).Nothing"


Reads = tuple[Sequence[object], Sequence[object]]


@pytest.fixture(autouse=True)
def nothing_said_yet(monkeypatch: pytest.MonkeyPatch) -> None:
    """Refused sums are logged once per target in a process: each test
    starts as a fresh process (the in-process targets share one address)."""
    monkeypatch.setattr(client_module, "_refused_sums_said", set(), raising=False)


async def _reads(client: AdsClient) -> Reads:
    """Handles of SYMBOLS + MISSING, then their values by handle."""
    handles = await client.acquire_handles([*SYMBOLS, MISSING])
    good = [h for h in handles if isinstance(h, int)]
    values = await client.read_by_handles([(h, 2) for h in good])
    return handles, values


def counted(target: SimTarget, monkeypatch: pytest.MonkeyPatch) -> RequestCounters:
    """The requests `target` answers from now on, by command and index group."""
    counters = RequestCounters()
    handle = target.handle

    def counting(packet: AmsPacket) -> AmsPacket | None:
        counters.count_request(packet)
        return handle(packet)

    monkeypatch.setattr(target, "handle", counting)
    return counters


SUM_GROUPS = (IndexGroup.SUMUP_READ, IndexGroup.SUMUP_READ_WRITE)
"""The sum commands `_reads` uses: 0xF082 for the handles, 0xF080 to read."""


def sums_asked(counters: RequestCounters) -> list[int]:
    return [counters.by_group[group] for group in SUM_GROUPS]


async def _both_ways(
    target: SimTarget, monkeypatch: pytest.MonkeyPatch
) -> tuple[Reads, Reads]:
    port = device_port(1)
    async with sim_clients(target) as clients:
        with_sums = await _reads(await clients(str(target.system_net_id), port))
    target.set_sum_commands(False)
    counters = counted(target, monkeypatch)
    async with sim_clients(target) as clients:
        client = await clients(str(target.system_net_id), port)
        single = await _reads(client)
        await _reads(client)
    assert sums_asked(counters) == [1, 1]  # refused once each, then never asked
    return with_sums, single


async def test_single_requests_give_what_sums_give(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Handles (and a missing symbol's own error) and values by handle are
    the same from single requests as from sums; each refused sum command is
    logged once, however many requests follow."""
    target = demo_target()
    with caplog.at_level(logging.WARNING):
        (handles, values), (single_handles, single_values) = await _both_ways(
            target, monkeypatch
        )
    said = [r.getMessage() for r in caplog.records if "single requests" in r.message]

    assert [type(h) for h in single_handles] == [type(h) for h in handles]
    assert all(isinstance(h, int) for h in handles[:-1])
    assert getattr(single_handles[-1], "code", None) == (
        AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    )
    assert len(single_values) == len(values) == len(SYMBOLS)
    assert all(isinstance(v, bytes) and len(v) == 2 for v in single_values)
    assert len(said) == 2, said
    assert any("sum reads (0xF080)" in line for line in said)
    assert any("sum read-writes (0xF082)" in line for line in said)


async def test_refused_sums_are_said_once_per_target_not_per_reconnect(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Issue 25: decided once per connection, said once per target: three
    connections (a reconnect each) to a target without sums give one line
    per refused sum command; the later ones decide the same at debug level."""
    target = demo_target()
    target.set_sum_commands(False)
    port = device_port(1)
    with caplog.at_level(logging.DEBUG, logger=client_module.__name__):
        for _ in range(3):
            async with sim_clients(target) as clients:
                client = await clients(str(target.system_net_id), port)
                await _reads(client)
    said = [r for r in caplog.records if "single requests" in r.message]

    assert [r.levelno for r in said] == [logging.WARNING] * 2 + [logging.DEBUG] * 4


async def test_a_sum_read_answer_from_single_reads_keeps_item_errors() -> None:
    """`sum_read` gives the raw 0xF080 answer the poller views with numpy,
    built from single reads: per item its result, a failed item's bytes
    zero."""
    target = demo_target()
    target.set_sum_commands(False)
    async with sim_clients(target) as clients:
        client = await clients(str(target.system_net_id), device_port(1))
        handles = await client.acquire_handles(SYMBOLS[:2])
        items = [
            SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, h, 2)
            for h in handles
            if isinstance(h, int)
        ]
        items.append(SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, 0xDEAD, 2))
        answers = [await client.sum_read(items) for _ in range(3)]
        (answer,) = answers[-1]
        decoded = SumReadResponse.decode(answer, [2, 2, 2])

    assert decoded.results[:2] == (0, 0)
    assert decoded.results[2] != 0
    assert decoded.data[2] == b"\0\0"


async def test_sums_again_on_a_new_connection(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The decision is per connection: a client of a new connection to a
    target that serves sums again uses them."""
    target = demo_target()
    counters = counted(target, monkeypatch)
    target.set_sum_commands(False)
    port = device_port(1)
    async with sim_clients(target) as clients:
        client = await clients(str(target.system_net_id), port)
        await _reads(client)
        await _reads(client)
        refused = sums_asked(counters)
    target.set_sum_commands(True)
    async with sim_clients(target) as clients:
        client = await clients(str(target.system_net_id), port)
        await _reads(client)
        await _reads(client)
        served = sums_asked(counters)

    assert refused == [1, 1]  # each refused once, then never asked again
    assert served == [3, 3]  # and both reads of the new connection in sums


@pytest.mark.parametrize("size", [8, 16, 20])
async def test_a_short_upload_info_answer_is_used(
    size: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 0xF00F answer shorter than 24 bytes (some targets answer 20) gives
    the symbol count and table size from its first 8 bytes, as pyads and
    fastcs-catio read it; the tables upload as with the full answer."""
    target = demo_target()
    port = device_port(1)
    async with sim_clients(target) as clients:
        full = await (await clients(str(target.system_net_id), port)).upload_symbols()

    async with sim_clients(target) as clients:
        client = await clients(str(target.system_net_id), port)
        original = client.read

        async def short(group: int, offset: int, length: int, **kw: bool) -> bytes:
            data = await original(group, offset, length, **kw)
            return data[:size] if group == IndexGroup.SYM_UPLOAD_INFO_2 else data

        monkeypatch.setattr(client, "read", short)
        tables = await client.upload_symbols()

    assert tables.info.symbol_count == full.info.symbol_count
    assert [s.name for s in tables.symbols] == [s.name for s in full.symbols]
    assert len(tables.data_types) == len(full.data_types)
