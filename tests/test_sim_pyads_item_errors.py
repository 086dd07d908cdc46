"""Per-item ADS errors in a sum read: the `error` fault with `symbols`.

pyads (Beckhoff's AdsLib) against `fastcs-ethercat sim` in its own process:
`read_list_by_name` learns each symbol's address with 0xF009 and then sum
reads them in one 0xF080; a failing symbol comes back as its error text
while the others keep their values, as a real TwinCAT answers per item.
The raw 0xF080 answer is checked through our codec too, so the result codes
themselves are asserted, not only pyads' reading of them.
"""

from __future__ import annotations

from collections.abc import Iterator

import pyads
import pyads.pyads_ex
import pytest
from pyads.structs import SAdsSumRequest

from fastcs_ethercat.ads.constants import AdsReturnCode, IndexGroup
from fastcs_ethercat.ads.sums import SumReadResponse
from fastcs_ethercat.sim.faults import parse_fault
from fastcs_ethercat.sim.process import SimProcess, SimProcessError
from tests.conftest import TERMINALS_DIR

NET_ID = "192.0.2.71.1.1"
DEVICE_PORT = 27905
TIMEOUT_MS = 5000
CHAIN = f"""\
system:
  net_id: {NET_ID}
masters:
- name: Device 1 (EtherCAT)
  slaves:
  - type: EK1100
  - type: EL3104
    signals:
      AI Standard Channel 1.Value: {{kind: constant, value: 111}}
      AI Standard Channel 2.Value: {{kind: constant, value: 222}}
  - type: EL1014
    signal: {{kind: constant, value: 1}}
"""
VALUE_1 = "Term 2 (EL3104).AI Standard Channel 1.Value"
VALUE_2 = "Term 2 (EL3104).AI Standard Channel 2.Value"
STATUS_1 = "Term 2 (EL3104).AI Standard Channel 1.Status"
CHANNEL_1 = "Term 2 (EL3104).AI Standard Channel 1"
DIGITAL = "Term 3 (EL1014).Channel 1"  # a BIT in the bit-addressed image
SIZES = {VALUE_1: 2, VALUE_2: 2, STATUS_1: 2, CHANNEL_1: 4, DIGITAL: 1}
"""Bytes of each (a BIT reads as one byte of the bit image)."""
NOT_READY = int(AdsReturnCode.DEVICE_NOT_READY)  # 0x707
ERROR_TEXTS = pyads.pyads_ex.ERROR_CODES


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimProcess]:
    chain = tmp_path_factory.mktemp("chain") / "chain.yaml"
    chain.write_text(CHAIN)
    with SimProcess(chain, terminals=TERMINALS_DIR) as process:
        yield process


@pytest.fixture(scope="module")
def device(sim: SimProcess) -> Iterator[pyads.Connection]:
    connection = pyads.Connection(NET_ID, DEVICE_PORT, sim.pyads_ip)
    connection.open()
    connection.set_timeout(TIMEOUT_MS)
    try:
        yield connection
    finally:
        connection.close()


@pytest.fixture
def plc(sim: SimProcess, device: pyads.Connection) -> Iterator[pyads.Connection]:
    sim.clear_faults()
    yield device
    sim.clear_faults()


def _raw_sum_read(device: pyads.Connection, names: list[str]) -> list[int]:
    """The per-item results of one 0xF080 of `names`' addresses, sent by
    pyads as its own sum reads are (an array of SAdsSumRequest)."""
    requests = (SAdsSumRequest * len(names))()
    for request, name in zip(requests, names, strict=True):
        info = device.get_symbol(name)
        request.iGroup = info.index_group
        request.iOffset = info.index_offset
        request.size = SIZES[name]
    raw = device.read_write(
        IndexGroup.SUMUP_READ, len(names), None, requests, None, return_ctypes=True
    )
    lengths = [int(request.size) for request in requests]
    return list(SumReadResponse.decode(bytes(raw), lengths).results)


@pytest.mark.e2e
def test_only_the_failing_symbol_fails_in_read_list_by_name(
    sim: SimProcess, plc: pyads.Connection
) -> None:
    names = [VALUE_1, VALUE_2, DIGITAL]  # pyads cannot decode the Status struct
    before = plc.read_list_by_name(names)
    applied = sim.add_fault("error", code=NOT_READY, symbols=[VALUE_1])
    during = plc.read_list_by_name(names)
    raw = _raw_sum_read(plc, [*names, STATUS_1])
    sim.clear_faults()
    after = plc.read_list_by_name(names)

    assert before == {VALUE_1: 111, VALUE_2: 222, DIGITAL: True}
    assert applied["applied"] == {
        "kind": "error",
        "code": NOT_READY,
        "symbols": [VALUE_1],
    }
    assert {"kind": "error", "code": NOT_READY, "symbols": [VALUE_1]} in applied[
        "active"
    ]
    assert during[VALUE_1] == ERROR_TEXTS[NOT_READY]
    assert during[VALUE_2] == 222
    assert raw == [NOT_READY, 0, 0, 0]  # Status: the neighbour in the struct
    assert after == {**during, VALUE_1: 111}


@pytest.mark.e2e
def test_a_structure_fails_with_every_member_and_a_bit_on_its_own(
    sim: SimProcess, plc: pyads.Connection
) -> None:
    sim.add_fault("error", code=1793, symbols=[CHANNEL_1])
    sim.add_fault("error", code=NOT_READY, symbols=DIGITAL)
    raw = _raw_sum_read(plc, [VALUE_1, STATUS_1, VALUE_2, DIGITAL, CHANNEL_1])
    faults = sim.request("GET", "/faults")["active"]

    assert raw == [1793, 1793, 0, NOT_READY, 1793]
    assert len(faults) == 2


@pytest.mark.e2e
def test_single_reads_of_a_failing_symbol_fail_too(
    sim: SimProcess, plc: pyads.Connection
) -> None:
    sim.add_fault("error", code=NOT_READY, symbols=[VALUE_2])
    with pytest.raises(pyads.ADSError) as by_name:
        plc.read_by_name(VALUE_2, pyads.PLCTYPE_INT)
    info = plc.get_symbol(VALUE_2)
    group, offset = info.index_group, info.index_offset
    assert group is not None and offset is not None
    with pytest.raises(pyads.ADSError) as by_address:
        plc.read(group, offset, pyads.PLCTYPE_INT)
    neighbour = plc.read_by_name(VALUE_1, pyads.PLCTYPE_INT)

    assert by_name.value.err_code == NOT_READY
    assert by_address.value.err_code == NOT_READY
    assert neighbour == 111


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"code": 1793, "symbols": ["Term 9 (EL3104).Nope"]}, "no symbol"),
        ({"code": 1793, "symbols": []}, "list of TwinCAT symbol names"),
        ({"code": 1793, "symbols": [VALUE_1], "group": 0xF020}, "not both"),
    ],
)
def test_bad_symbol_faults_are_refused_with_400(
    sim: SimProcess, params: dict[str, object], message: str
) -> None:
    with pytest.raises(SimProcessError) as refused:
        sim.add_fault("error", **params)

    assert " 400 " in str(refused.value) and message in str(refused.value)
    assert sim.request("GET", "/faults")["active"] == []


def test_fault_parameters_round_trip() -> None:
    fault = parse_fault({"kind": "error", "code": "0x710", "symbols": VALUE_1})

    assert fault.to_json() == {"kind": "error", "code": 0x710, "symbols": [VALUE_1]}
