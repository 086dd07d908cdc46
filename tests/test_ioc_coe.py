"""CoE SDO access through the master to a slave's mailbox port (real simulator)."""

from __future__ import annotations

from collections.abc import AsyncIterator, Iterator

import pytest

from fastcs_ethercat.ads.client import AdsError
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.coe import SlaveCoe, decode_coe, encode_coe, sdo_offset
from fastcs_ethercat.ioc.plan import CoePoint
from fastcs_ethercat.ioc.resolve import coe_points
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals import load_terminals
from tests.conftest import TERMINALS_DIR

CHAIN = """\
system:
  net_id: 127.0.0.1.1.1
masters:
- name: Device 1 (EtherCAT)
  slaves:
  - type: EK1100
  - type: EL3104
"""
MASTER_NET_ID = "127.0.0.1.2.1"
EL3104_ADDRESS = 1002


def el3104_points() -> dict[str, CoePoint]:
    """Every sub-item of the EL3104's objects, as if the YAML selected them."""
    terminal = load_terminals([TERMINALS_DIR]).get("EL3104").terminal
    terminal = terminal.model_copy(deep=True)
    for obj in terminal.coe_objects:
        obj.selected = True
        for sub in obj.sub_items:  # the shipped file selects 0x8000:06 alone
            sub.selected = True
    return {p.attribute: p for p in coe_points(terminal)}


POINTS = el3104_points()


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimProcess]:
    chain = tmp_path_factory.mktemp("chain") / "chain.yaml"
    chain.write_text(CHAIN)
    with SimProcess(chain, terminals=TERMINALS_DIR) as process:
        yield process


@pytest.fixture
async def coe(sim: SimProcess) -> AsyncIterator[SlaveCoe]:
    async with ClientPool(sim.host, sim.tcp_port) as pool:
        yield SlaveCoe(pool, MASTER_NET_ID, EL3104_ADDRESS)


@pytest.mark.e2e
async def test_read_defaults(coe: SlaveCoe) -> None:
    assert await coe.read(POINTS["ai_settings_8000_user_calibration_gain"]) == 0x4000
    assert await coe.read(POINTS["ai_settings_8000_enable_vendor_calibration"]) is True
    assert await coe.read(POINTS["ai_settings_8000_enable_filter"]) is False
    assert await coe.read(POINTS["identity_1018_vendor_id"]) == 2
    assert await coe.read(POINTS["device_name_1008"]) == "EL3104"


@pytest.mark.e2e
async def test_write_reads_back(coe: SlaveCoe) -> None:
    offset = POINTS["ai_settings_8010_user_scale_offset"]
    await coe.write(offset, -123)
    assert await coe.read(offset) == -123
    presentation = POINTS["ai_settings_8010_presentation"]
    await coe.write(presentation, 2)
    assert await coe.read(presentation) == 2
    enable = POINTS["ai_settings_8010_enable_limit_1"]
    await coe.write(enable, True)
    assert await coe.read(enable) is True
    # Its neighbours in the same byte are untouched.
    assert await coe.read(POINTS["ai_settings_8010_enable_limit_2"]) is False
    assert await coe.read(presentation) == 2


@pytest.mark.e2e
async def test_refusals_are_ads_errors(coe: SlaveCoe) -> None:
    with pytest.raises(AdsError) as refused:
        await coe.write(POINTS["identity_1018_vendor_id"], 5)
    assert refused.value.code != 0
    missing = CoePoint("missing", 0x7FFF, 1, "UINT", 16, writable=False)
    with pytest.raises(AdsError):
        await coe.read(missing)


def test_codec() -> None:
    assert sdo_offset(0x8000, 0x11) == 0x80000011
    gain = POINTS["ai_settings_8000_user_scale_gain"]
    assert decode_coe(gain, encode_coe(gain, -5)) == -5
    presentation = POINTS["ai_settings_8000_presentation"]
    assert encode_coe(presentation, 3) == b"\x03"
    with pytest.raises(ValueError):
        encode_coe(presentation, 8)


def test_byte_array_objects_decode_to_what_their_waveform_takes() -> None:
    """ELM3704 diagnosis messages (`ARRAY [0..21] OF BYTE`): an array, not one
    number (which the Waveform refused, once per value, with a traceback)."""
    from fastcs_ethercat.ioc.attributes import coe_datatype

    point = CoePoint("message", 0x10F3, 6, "ARRAY [0..21] OF BYTE", 176, False)
    raw = bytes(range(22))
    value = decode_coe(point, raw)
    assert coe_datatype(point).validate(value).tolist() == list(range(22))
    assert encode_coe(point, value) == raw
    assert decode_coe(point, raw[:5]).tolist() == [0, 1, 2, 3, 4]
