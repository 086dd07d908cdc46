"""`fastcs-ethercat ioc --read-only` end to end: no ADS write, ever.

One simulator (fresh, so its counters cover the IOC's whole run) and one IOC
started with `--read-only`. Outputs and CoE parameters are served as read
PVs: a caput is refused and the client is told so (CA "Channel write request
failed", PVA "Put not supported"), nothing reaches the PLC, each such PV's
DESC starts with "(read-only)", and after the IOC has stopped the simulator
has counted no Write, no WriteControl and no sum write at all.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from fastcs_ethercat.ioc.attributes import READ_ONLY_MARK
from fastcs_ethercat.sim.process import SimProcess
from tests.ioc_support import (
    IocProcess,
    caget,
    served_ioc,
    terminals_with_coe,
    wait_for,
)

pytestmark = pytest.mark.e2e

CHAIN = """\
system:
  net_id: 127.0.0.1.1.1
masters:
- name: Device 1 (EtherCAT)
  slaves:
  - type: EK1100
  - type: EL2024
  - type: EL4134
  - type: EL3104
"""
DIGITAL_OUT = "ETH1:RIO1:MOD2:CH3:Output"
DIGITAL_SYMBOL = "Term 2 (EL2024).Channel 3"
ANALOG_OUT = "ETH1:RIO1:MOD3:CH1:AnalogOutput"
ANALOG_SYMBOL = "Term 3 (EL4134).AO Output Channel 1"
INPUT = "ETH1:RIO1:MOD4:CH1:Value"
COE = "ETH1:RIO1:MOD4:C8000:CoeOffset"
COE_PATH = (
    "Device 1 (EtherCAT)^Term 1 (EK1100)^Term 4 (EL3104)"
    "^Coe ai_settings_8000_user_scale_offset"
)
REFUSED_CA = "Write access denied"


@dataclass
class ReadOnlyRig:
    sim: SimProcess
    ioc: IocProcess

    def pv(self, name: str) -> str:
        return self.ioc.pv(name)


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ReadOnlyRig]:
    work = tmp_path_factory.mktemp("readonly")
    chain = work / "chain.yaml"
    chain.write_text(CHAIN)

    def config(sim: SimProcess, prefix: str) -> Path:
        path = work / "ioc.yaml"
        settings = {
            "prefix": prefix,
            "target": sim.pyads_ip,
            "ams_net_id": sim.net_id,
            "terminal_dirs": [str(terminals_with_coe(work / "terminals"))],
            "pv_aliases": {COE_PATH: "CoeOffset"},
        }
        path.write_text(yaml.safe_dump(settings))
        return path

    # The simulator outside the IOC's token: stopping the IOC must leave it
    # up for the final count.
    with served_ioc("RO", chain, config, "--read-only", sim_shares_ioc_env=False) as (
        sim,
        ioc,
    ):
        yield ReadOnlyRig(sim, ioc)


def test_puts_to_outputs_and_coe_are_refused_and_say_why(rig: ReadOnlyRig) -> None:
    ioc = rig.ioc
    pvs = {name: rig.pv(name) for name in (DIGITAL_OUT, ANALOG_OUT, COE, INPUT)}
    assert wait_for(lambda: caget(ioc, pvs[COE]).get(pvs[COE]) == "0", 10)

    puts = {
        name: ioc.tool("caput", pvs[name], value)
        for name, value in ((DIGITAL_OUT, "1"), (ANALOG_OUT, "1234"), (COE, "55"))
    }
    pva_put = ioc.tool("pvput", pvs[ANALOG_OUT], "4321")
    access = {name: ioc.tool("cainfo", pvs[name]) for name in pvs}
    after = caget(ioc, *pvs.values())
    descriptions = caget(ioc, *(pv + ".DESC" for pv in pvs.values()))
    readbacks = caget(ioc, *(pvs[name] + "_RBV" for name in (ANALOG_OUT, COE)))

    for name, output in puts.items():
        assert REFUSED_CA in output, (name, output)
    assert "Put not permitted" in pva_put, pva_put  # QSRV asks the same ACF
    assert after[pvs[DIGITAL_OUT]] in ("0", "False")
    assert after[pvs[ANALOG_OUT]] == "0"
    assert after[pvs[COE]] == "0"
    assert rig.sim.get_symbol(DIGITAL_SYMBOL) in (0, False)
    assert rig.sim.get_symbol(ANALOG_SYMBOL) == 0
    for name in (DIGITAL_OUT, ANALOG_OUT, COE):
        assert descriptions[pvs[name] + ".DESC"].startswith(READ_ONLY_MARK.strip())
    assert not descriptions[pvs[INPUT] + ".DESC"].startswith(READ_ONLY_MARK.strip())
    assert readbacks == {}  # read-only outputs have one PV, no setpoint/_RBV pair
    for name in (DIGITAL_OUT, ANALOG_OUT, COE):  # Phoebus greys these out
        assert "read, no write" in access[name], access[name]
    assert "read, write" in access[INPUT]


def test_no_ads_write_in_the_whole_run(rig: ReadOnlyRig) -> None:
    """Last in the module: stops the IOC, then reads the simulator's counts."""
    connected = rig.pv("Connected")
    assert wait_for(lambda: caget(rig.ioc, connected).get(connected) == "True", 10)
    rig.ioc.stop()
    counters = rig.sim.counters()
    commands, groups = counters["commands"], counters["index_groups"]

    assert rig.ioc.child.returncode is not None
    assert commands.get("READ_WRITE", 0) > 0  # it did poll (sum reads)
    assert commands.get("WRITE", 0) == 0, commands
    assert commands.get("WRITE_CONTROL", 0) == 0, commands
    assert groups.get("0xF081", 0) == 0, groups  # no sum write either
    assert groups.get("0xF302", 0) > 0  # the CoE value was read, never written
