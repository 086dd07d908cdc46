"""What an independent client (fastcs-catio's, written against real racks)
found the simulator did differently from TwinCAT, checked with pyads
(Beckhoff's AdsLib) against the simulator in this process, and the IOC's
client on a target with the services of an older TwinCAT.

Facts: `../shared/reference/ads-twincat-facts.md` section 9; the CRC totals
are Beckhoff's FB_EcGetAllSlaveCrcErrors (the ports of each slave added).
"""

from __future__ import annotations

import asyncio
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Final

import pyads
import pytest
import yaml

from fastcs_ethercat.ads.client import AdsClient, AdsHandleInvalidError
from fastcs_ethercat.ads.constants import AdsReturnCode, EtherCatMasterGroup
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.twincat.target import SimTarget
from tests.ads_codec import decode_crc_totals
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.sim_thread import SimulatorThread

NET_ID: Final = "192.0.2.63.1.1"
DEVICE_NET_ID: Final = "192.0.2.63.2.1"
OLD_NET_ID: Final = "192.0.2.64.1.1"
DEVICE_PORT: Final = 27905
STANDARD: Final = "Term 22 (EL3104).AI Standard Channel 1"
"""A 4-byte structure: Status (UINT) at +0, Value (INT) at +2."""
COMPACT: Final = "Term 5 (EL3104).AI Compact Channel 1"
"""An INT."""


def chain_file(folder: Path, net_id: str, **system: Any) -> Path:
    chain = yaml.safe_load((REPO_ROOT / "ioc" / "demo-chain.yaml").read_text())
    chain["system"].update(net_id=net_id, **system)
    path = folder / f"{net_id}.yaml"
    path.write_text(yaml.safe_dump(chain, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimulatorThread]:
    chain = chain_file(tmp_path_factory.mktemp("fidelity"), NET_ID)
    target = SimTarget.from_chain(chain, TERMINALS_DIR)
    with SimulatorThread(target) as thread:
        yield thread


def connect(sim: SimulatorThread, net_id: str, port: int) -> pyads.Connection:
    connection = pyads.Connection(net_id, port, f"127.0.0.1:{sim.endpoints.tcp_port}")
    connection.open()
    connection.set_timeout(5000)
    return connection


@pytest.fixture(scope="module")
def device(sim: SimulatorThread) -> Iterator[pyads.Connection]:
    connection = connect(sim, NET_ID, DEVICE_PORT)
    yield connection
    connection.close()


def handle_of(device: pyads.Connection, name: str) -> int:
    handle = device.get_handle(name)
    assert handle is not None
    return handle


def target_of(sim: SimulatorThread) -> SimTarget:
    target = sim.simulator.target
    assert isinstance(target, SimTarget)
    return target


def set_value(sim: SimulatorThread, name: str, value: Any) -> None:
    sim.call(lambda: target_of(sim).set_symbol_value(name, value))


def test_crc_counters_of_every_slave_at_once(sim: SimulatorThread) -> None:
    runtimes = target_of(sim).devices[0].ethercat.slaves
    ports = [[n, 2 * n, 0, 1] for n in range(len(runtimes))]
    for runtime, counters in zip(runtimes, ports, strict=True):
        runtime.crc = counters
    master = connect(sim, DEVICE_NET_ID, 0xFFFF)
    try:
        count = len(runtimes)
        totals = master.read(
            EtherCatMasterGroup.SLAVE_CRC_COUNTERS, 0, pyads.PLCTYPE_UDINT * count
        )
        one = master.read(
            EtherCatMasterGroup.SLAVE_CRC_COUNTERS, 1003, pyads.PLCTYPE_UDINT * 4
        )
    finally:
        master.close()
        for runtime in runtimes:
            runtime.crc = [0, 0, 0, 0]

    assert list(totals) == [sum(counters) for counters in ports]
    assert list(one) == ports[2]
    assert decode_crc_totals(struct.pack("<3I", 1, 2, 3)) == (1, 2, 3)


def test_a_shorter_read_returns_the_first_bytes(
    sim: SimulatorThread, device: pyads.Connection
) -> None:
    set_value(sim, STANDARD, {"Status": {"Error": True}, "Value": -2})
    whole = device.read_by_name(STANDARD, pyads.PLCTYPE_BYTE * 4)
    handle = handle_of(device, STANDARD)
    try:
        status = device.read_by_name("", pyads.PLCTYPE_UINT, handle=handle)
        first = device.read_by_name("", pyads.PLCTYPE_BYTE, handle=handle)
    finally:
        device.release_handle(handle)

    assert bytes(whole)[2:] == struct.pack("<h", -2)
    assert status == struct.unpack("<H", bytes(whole)[:2])[0] != 0
    assert first == bytes(whole)[0]


def test_a_shorter_notification_carries_the_first_bytes(
    sim: SimulatorThread, device: pyads.Connection
) -> None:
    set_value(sim, STANDARD, {"Value": 0x1234})
    received: list[bytes] = []

    def callback(notification: Any, _name: str) -> None:
        _, _, value = device.parse_notification(notification, pyads.PLCTYPE_BYTE * 2)
        received.append(bytes(value))

    attr = pyads.NotificationAttrib(2, trans_mode=pyads.ADSTRANS_SERVERCYCLE)
    handles = device.add_device_notification(STANDARD, attr, callback)
    assert handles is not None
    time.sleep(0.3)
    device.del_device_notification(*handles)

    whole = bytes(device.read_by_name(STANDARD, pyads.PLCTYPE_BYTE * 4))
    assert received
    assert set(received) == {whole[:2]}


def test_a_notification_longer_than_its_symbol_is_refused(
    device: pyads.Connection,
) -> None:
    attr = pyads.NotificationAttrib(8, trans_mode=pyads.ADSTRANS_SERVERONCHA)

    with pytest.raises(pyads.ADSError) as refused:
        device.add_device_notification(COMPACT, attr, lambda *_: None)

    assert refused.value.err_code == AdsReturnCode.DEVICE_INVALID_SIZE


def test_a_write_of_the_wrong_size_is_refused(
    sim: SimulatorThread, device: pyads.Connection
) -> None:
    name = "Term 15 (EL4134).AO Output Channel 1"  # an INT
    device.write_by_name(name, 1234, pyads.PLCTYPE_INT)

    with pytest.raises(pyads.ADSError) as refused:
        device.write_by_name(name, 99, pyads.PLCTYPE_DINT)

    assert refused.value.err_code == AdsReturnCode.DEVICE_INVALID_SIZE
    assert device.read_by_name(name, pyads.PLCTYPE_INT) == 1234


def test_handles_taken_before_an_online_change_fail_with_0x711(
    sim: SimulatorThread, device: pyads.Connection
) -> None:
    handle = handle_of(device, COMPACT)
    device.read_by_name("", pyads.PLCTYPE_INT, handle=handle)
    sim.call(lambda: target_of(sim).online_change())

    with pytest.raises(pyads.ADSError) as outdated:
        device.read_by_name("", pyads.PLCTYPE_INT, handle=handle)
    with pytest.raises(pyads.ADSError) as unknown:
        device.read_by_name("", pyads.PLCTYPE_INT, handle=0x7FFF_FFF0)
    fresh = handle_of(device, COMPACT)
    value = device.read_by_name("", pyads.PLCTYPE_INT, handle=fresh)
    device.release_handle(fresh)
    device.release_handle(handle)

    assert outdated.value.err_code == AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID
    assert unknown.value.err_code == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND
    assert isinstance(value, int)


def test_the_ioc_client_by_handle_agrees_with_pyads(
    sim: SimulatorThread, device: pyads.Connection
) -> None:
    names = [COMPACT, STANDARD, "Term 99 (EL0000).Nothing"]
    set_value(sim, STANDARD, {"Value": 77})

    async def by_handle() -> tuple[list[Any], list[Any], BaseException | None]:
        async with AdsClient(
            "127.0.0.1", NET_ID, DEVICE_PORT, tcp_port=sim.endpoints.tcp_port
        ) as client:
            handles = await client.acquire_handles(names)
            good = [h for h in handles if isinstance(h, int)]
            values = await client.read_by_handles(list(zip(good, (2, 4), strict=True)))
            await client.write_by_handle(good[0], b"\x01\x00")
            sim.call(lambda: target_of(sim).online_change())
            stale = await client.read_by_handles([(good[1], 4)])
            await client.release_handles(good)
            return (
                handles,
                values,
                stale[0] if isinstance(stale[0], BaseException) else None,
            )

    handles, values, stale = asyncio.run(by_handle())

    assert [type(h) for h in handles[:2]] == [int, int]
    assert isinstance(handles[2], Exception)
    assert values[1] == bytes(device.read_by_name(STANDARD, pyads.PLCTYPE_BYTE * 4))
    assert isinstance(stale, AdsHandleInvalidError)


def test_the_ioc_client_on_an_older_twincat(tmp_path: Path) -> None:
    """No 0xF00F (only 0xF00C, 8 bytes) and no symbol version on the device
    port: the upload falls back, discovery does not depend on 0xF008."""
    chain = chain_file(
        tmp_path,
        OLD_NET_ID,
        upload_info_2=False,
        symbol_version_on_device_port=False,
    )
    target = SimTarget.from_chain(chain, TERMINALS_DIR)
    with SimulatorThread(target) as old:
        port = old.endpoints.tcp_port
        pyads_device = connect(old, OLD_NET_ID, DEVICE_PORT)
        try:
            info = pyads_device.read(0xF00C, 0, pyads.PLCTYPE_UDINT * 2)
            with pytest.raises(pyads.ADSError) as no_info_2:
                pyads_device.read(0xF00F, 0, pyads.PLCTYPE_UDINT * 6)
        finally:
            pyads_device.close()

        async def upload() -> tuple[Any, int | None, SystemPlan]:
            async with AdsClient(
                "127.0.0.1", OLD_NET_ID, DEVICE_PORT, tcp_port=port
            ) as c:
                tables, version = (
                    await c.upload_symbols(),
                    await c.read_symbol_version(),
                )
            config = IocConfig(
                prefix="OLD", target=f"127.0.0.1:{port}", ams_net_id=OLD_NET_ID
            )
            async with ClientPool(config.target_host, config.target_port) as pool:
                plan = await discover(pool, load_terminals([TERMINALS_DIR]), config)
            return tables, version, plan

        tables, version, plan = asyncio.run(upload())

    assert no_info_2.value.err_code == AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED
    assert version is None
    assert len(tables.symbols) == info[0] > 100
    assert tables.info.symbol_table_size == info[1]
    assert tables.data_types  # read as far as the table goes
    assert {s.name for s in tables.symbols} >= {COMPACT, STANDARD}
    assert plan.symbol_version == -1  # discovery does not need 0xF008
    served = [p for t in plan.masters[0].terminals for p in t.points]
    assert len(plan.masters[0].terminals) == 24 and len(served) > 100
