"""pyads (Beckhoff's AdsLib) against `fastcs-ethercat sim` in its own process.

The chain is the demo chain with its own NetId (so no other test's AdsLib
route can clash with ours) and 110 more EL1014 terminals, which pushes the
symbol table past 500 entries for `read_list_by_name`. pyads reaches the
simulator's free TCP port through AdsLib's "host:port" form of the address.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pyads
import pyads.pyads_ex
import pytest
import yaml

from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT

pytestmark = pytest.mark.e2e

NET_ID = "192.0.2.61.1.1"
DEVICE_NET_ID = "192.0.2.61.2.1"
EXTRA_EL1014 = 110
DEMO_SLAVES = 24
DEVICE_PORT = 27905
TIMEOUT_MS = 5000


def write_chain(path: Path) -> Path:
    """The demo chain with our NetId and EXTRA_EL1014 more digital inputs,
    all held at 0 (the default generator would toggle them)."""
    chain = yaml.safe_load((REPO_ROOT / "ioc" / "demo-chain.yaml").read_text())
    chain["system"]["net_id"] = NET_ID
    quiet = {"type": "EL1014", "signal": {"kind": "constant", "value": 0}}
    chain["masters"][0]["slaves"] += [quiet] * EXTRA_EL1014
    path.write_text(yaml.safe_dump(chain, sort_keys=False))
    return path


def extra_term(k: int) -> str:
    """TwinCAT name of the k-th extra EL1014 (k from 0)."""
    return f"Term {DEMO_SLAVES + 1 + k} (EL1014)"


@dataclass
class Plc:
    sim: SimProcess
    device: pyads.Connection
    io_server: pyads.Connection
    master: pyads.Connection


@pytest.fixture(scope="module")
def plc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Plc]:
    chain = write_chain(tmp_path_factory.mktemp("chain") / "chain.yaml")
    with SimProcess(chain, terminals=REPO_ROOT / "terminals") as sim:
        assert sim.net_id == NET_ID
        connections = [
            pyads.Connection(NET_ID, DEVICE_PORT, sim.pyads_ip),
            pyads.Connection(NET_ID, 300, sim.pyads_ip),
            pyads.Connection(DEVICE_NET_ID, 0xFFFF, sim.pyads_ip),
        ]
        for connection in connections:
            connection.open()
            connection.set_timeout(TIMEOUT_MS)
        try:
            yield Plc(sim, *connections)
        finally:
            for connection in connections:
                connection.close()


@pytest.fixture
def counted(plc: Plc) -> Iterator[Plc]:
    plc.sim.reset_counters()
    yield plc
    plc.sim.clear_faults()


def test_device_info_and_state(plc: Plc) -> None:
    info = plc.io_server.read_device_info()
    assert info is not None
    name, version = info
    assert name == "I/O Server"
    assert (version.version, version.revision) == (3, 1)
    assert plc.io_server.read_state() == (pyads.ADSSTATE_RUN, 0)
    assert plc.device.read_state() == (pyads.ADSSTATE_RUN, 0)


def test_symbol_upload(plc: Plc) -> None:
    symbols = {symbol.name: symbol for symbol in plc.device.get_all_symbols()}
    assert len(symbols) == plc.sim.status()["model"]["symbols"]
    assert len(symbols) > 500
    compact = symbols["Term 5 (EL3104).AI Compact Channel 1"]
    assert compact.symbol_type == "INT"
    standard = symbols["Term 22 (EL3104).AI Standard Channel 1"]
    assert standard.symbol_type == "AI Standard Channel 1_TYPE"
    assert symbols[f"{extra_term(0)}.Channel 1"].symbol_type == "BIT"
    assert {s.index_group for s in symbols.values()} <= {
        0xF020,
        0xF021,
        0xF030,
        0xF031,
    }


def test_read_and_write_by_name(counted: Plc) -> None:
    plc = counted
    name = "Term 22 (EL3104).AI Standard Channel 1.Value"
    plc.sim.set_symbol(name, -1234)
    assert plc.device.read_by_name(name, pyads.PLCTYPE_INT) == -1234
    output = "Term 6 (EL2024).Channel 3"
    for value in (True, False, True):
        plc.device.write_by_name(output, value, pyads.PLCTYPE_BOOL)
        assert plc.sim.get_symbol(output) is value
        assert plc.device.read_by_name(output, pyads.PLCTYPE_BOOL) is value
    assert plc.sim.counters()["index_groups"]["0xF003"] >= 4  # handles by name


def test_read_list_by_name_with_more_than_500_symbols(counted: Plc) -> None:
    plc = counted
    names = [
        f"{extra_term(k)}.Channel {channel}"
        for k in range(EXTRA_EL1014)
        for channel in (1, 2, 3, 4)
    ] + [f"{extra_term(k)}.WcState.WcState" for k in range(EXTRA_EL1014)]
    assert len(names) == 550
    for k in range(0, EXTRA_EL1014, 7):
        plc.sim.set_symbol(f"{extra_term(k)}.Channel 2", True)
    values = plc.device.read_list_by_name(names)
    assert set(values) == set(names)
    high = {n for n, v in values.items() if v is True}
    assert high == {f"{extra_term(k)}.Channel 2" for k in range(0, EXTRA_EL1014, 7)}
    groups = plc.sim.counters()["index_groups"]
    assert groups["0xF080"] == 2  # pyads splits at 500 sub-commands
    assert groups["0xF009"] == 550  # one info-by-name per symbol


@pytest.mark.parametrize(
    ("mode", "cycle_ms", "seconds", "expected"),
    [
        (pyads.ADSTRANS_SERVERCYCLE, 50, 1.0, range(15, 24)),
        (pyads.ADSTRANS_SERVERONCHA, 10, 0.5, range(1, 10**6)),
    ],
)
def test_notifications_with_real_timestamps(
    plc: Plc, mode: int, cycle_ms: int, seconds: float, expected: range
) -> None:
    name = "Term 5 (EL3104).AI Compact Channel 1"  # a sine, 4 s period
    received: list[tuple[int, datetime, int]] = []

    def callback(notification: Any, _name: str) -> None:
        handle, stamp, value = plc.device.parse_notification(
            notification, pyads.PLCTYPE_INT
        )
        assert isinstance(stamp, datetime)
        received.append((handle, stamp, value))

    attr = pyads.NotificationAttrib(
        2, trans_mode=mode, max_delay=0, cycle_time=cycle_ms
    )
    handles = plc.device.add_device_notification(name, attr, callback)
    assert handles is not None
    time.sleep(seconds)
    plc.device.del_device_notification(*handles)
    count = len(received)
    time.sleep(0.1)
    assert len(received) == count  # none after the delete
    assert count in expected
    assert {handle for handle, _, _ in received} == {handles[0]}
    stamps = [stamp for _, stamp, _ in received]
    assert stamps == sorted(stamps)
    now = datetime.now(UTC)
    assert now - timedelta(seconds=seconds + 5) < stamps[0] <= now
    if mode == pyads.ADSTRANS_SERVERCYCLE:
        gaps = [(b - a).total_seconds() for a, b in itertools.pairwise(stamps)]
        assert sum(gaps) / len(gaps) == pytest.approx(cycle_ms / 1000, rel=0.2)
    else:
        values = [value for _, _, value in received]
        assert all(a != b for a, b in itertools.pairwise(values))


def test_notifications_are_batched_within_max_delay(counted: Plc) -> None:
    plc = counted
    name = "Term 5 (EL3104).AI Compact Channel 1"
    received: list[Any] = []
    attr = pyads.NotificationAttrib(
        2, trans_mode=pyads.ADSTRANS_SERVERCYCLE, max_delay=200, cycle_time=10
    )
    handles = plc.device.add_device_notification(
        name, attr, lambda notification, _: received.append(notification)
    )
    assert handles is not None
    time.sleep(1.0)
    plc.device.del_device_notification(*handles)
    notifications = plc.sim.counters()["notifications"]
    assert notifications["samples"] >= 50
    assert notifications["frames"] <= 8  # about one frame per 200 ms


def test_coe_reads_and_writes(plc: Plc) -> None:
    slave = pyads.Connection(DEVICE_NET_ID, 1022, plc.sim.pyads_ip)  # Term 22
    slave.open()
    try:
        slave.set_timeout(TIMEOUT_MS)
        assert slave.read(0xF302, 0x1018 << 16 | 1, pyads.PLCTYPE_UDINT) == 2
        assert slave.read(0xF302, 0x1008 << 16, pyads.PLCTYPE_STRING) == "EL3104"
        limit = 0x8000 << 16 | 0x13
        assert slave.read(0xF302, limit, pyads.PLCTYPE_INT) == 0
        slave.write(0xF302, limit, -321, pyads.PLCTYPE_INT)
        assert slave.read(0xF302, limit, pyads.PLCTYPE_INT) == -321
        with pytest.raises(pyads.ADSError) as error:
            slave.read(0xF302, 0x7777 << 16, pyads.PLCTYPE_UDINT)
        assert error.value.err_code == 0x703
    finally:
        slave.close()


def test_master_queries(plc: Plc) -> None:
    slaves = DEMO_SLAVES + EXTRA_EL1014
    assert plc.master.read_state() == (pyads.ADSSTATE_RUN, 0)
    assert plc.master.read(0x06, 0, pyads.PLCTYPE_UINT) == slaves
    addresses = plc.master.read(0x07, 0, pyads.PLCTYPE_UINT * slaves)
    assert list(addresses) == list(range(1001, 1001 + slaves))
    states = plc.master.read(0x09, 0, pyads.PLCTYPE_BYTE * (2 * slaves))
    assert list(states[0::2]) == [8] * slaves  # OP
    assert list(states[1::2]) == [0] * slaves  # links fine
    identity = plc.master.read(0x11, 1005, pyads.PLCTYPE_UDINT * 4)
    assert identity[0] == 2  # Beckhoff
    plc.sim.add_fault("slave_state", address=1005, state="PREOP")
    try:
        assert plc.master.read(0x09, 1005, pyads.PLCTYPE_BYTE * 2)[0] == 2
    finally:
        plc.sim.clear_faults()


def test_faults_as_pyads_sees_them(counted: Plc) -> None:
    plc = counted
    plc.sim.add_fault("stop")
    assert plc.io_server.read_state() == (pyads.ADSSTATE_STOP, 0)
    plc.sim.clear_faults()
    plc.sim.add_fault("error", code=0x708, group=0xF00F)
    with pytest.raises(pyads.ADSError) as error:
        plc.device.get_all_symbols()
    assert error.value.err_code == 0x708
    plc.sim.clear_faults()
    assert plc.io_server.read_state() == (pyads.ADSSTATE_RUN, 0)


def test_discovery_and_route_add_over_udp(
    plc: Plc, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(pyads.pyads_ex, "PORT_REMOTE_UDP", plc.sim.udp_port)
    assert pyads.pyads_ex.adsGetNetIdForPLC("127.0.0.1") == NET_ID
    assert pyads.add_route_to_plc(
        "127.0.0.1.1.20", "127.0.0.1", "127.0.0.1", "Administrator", "1"
    )
