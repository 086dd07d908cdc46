"""Discovery against the simulator (real subprocess, real pyads): the demo chain."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from fastcs_ethercat.ads.ethercat import AlState
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig, split_host_port
from fastcs_ethercat.ioc.discovery import discover, read_symbol_version
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry
from tests.conftest import REPO_ROOT, TERMINALS_DIR

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"


def chain_types(path: Path) -> list[str]:
    document = yaml.safe_load(path.read_text())
    return [slave["type"] for slave in document["masters"][0]["slaves"]]


def discover_now(sim: SimProcess, registry: TerminalRegistry) -> SystemPlan:
    async def run() -> SystemPlan:
        config = IocConfig(prefix="TEST", target=sim.pyads_ip, ams_net_id=sim.net_id)
        async with ClientPool(config.target_host, config.target_port) as pool:
            return await discover(pool, registry, config)

    return asyncio.run(run())


@pytest.fixture(scope="module")
def registry() -> TerminalRegistry:
    return load_terminals([TERMINALS_DIR])


@pytest.fixture(scope="module")
def sim() -> Iterator[SimProcess]:
    with SimProcess(DEMO_CHAIN, terminals=TERMINALS_DIR) as process:
        yield process


@pytest.fixture(scope="module")
def plan(sim: SimProcess, registry: TerminalRegistry) -> SystemPlan:
    return discover_now(sim, registry)


@pytest.mark.e2e
def test_system_and_master(plan: SystemPlan, sim: SimProcess) -> None:
    assert plan.net_id == sim.net_id
    assert plan.device_name == "I/O Server"
    assert plan.symbol_version >= 1
    [master] = plan.masters
    assert (master.device_id, master.name) == (1, "Device 1 (EtherCAT)")
    assert master.net_id == "127.0.0.1.2.1"
    assert master.symbol_port == 27905


@pytest.mark.e2e
def test_every_slave_with_name_address_and_identity(
    plan: SystemPlan, registry: TerminalRegistry
) -> None:
    types = chain_types(DEMO_CHAIN)
    slaves = [terminal.slave for terminal in plan.masters[0].terminals]
    assert len(slaves) == len(types) == 24
    for position, (slave, type_name) in enumerate(zip(slaves, types, strict=True)):
        assert slave.position == position
        assert slave.address == 1001 + position
        assert slave.name == f"Term {position + 1} ({type_name})"
        assert slave.type_name == type_name
        identity = registry.get(type_name).terminal.identity
        found = slave.identity
        assert (found.vendor_id, found.product_code, found.revision) == (
            identity.vendor_id,
            identity.product_code,
            identity.revision_number,
        )
        assert slave.al_state & 0x0F == AlState.OP
        assert slave.link_state == 0


@pytest.mark.e2e
def test_terminals_matched_to_their_yaml(plan: SystemPlan) -> None:
    types = chain_types(DEMO_CHAIN)
    matched = [terminal.terminal_type for terminal in plan.masters[0].terminals]
    assert matched == types
    assert all(terminal.exact_revision for terminal in plan.masters[0].terminals)


@pytest.mark.e2e
def test_coupler_tree(plan: SystemPlan) -> None:
    slaves = {t.slave.name: t.slave for t in plan.masters[0].terminals}
    couplers = sorted(name for name, slave in slaves.items() if slave.is_coupler)
    assert couplers == ["Term 1 (EK1100)", "Term 18 (EK1100)", "Term 21 (EK1122)"]
    for slave in slaves.values():
        number = slave.position + 1
        if slave.is_coupler:
            assert slave.coupler is None
        elif number < 18:
            assert slave.coupler == "Term 1 (EK1100)"
        elif number < 21:
            assert slave.coupler == "Term 18 (EK1100)"
        else:
            assert slave.coupler == "Term 21 (EK1122)"


@pytest.mark.e2e
def test_master_points_from_inputs_and_outputs(plan: SystemPlan) -> None:
    points = {p.attribute: p for p in plan.masters[0].master_points}
    assert {"frm0_state", "frm0_wc_state", "slave_count", "dev_state"} <= set(points)
    assert {"frm0_ctrl", "dev_ctrl"} <= set(points)
    assert points["slave_count"].symbol == "Device 1 (EtherCAT).Inputs.SlaveCount"
    assert points["slave_count"].type_name == "UINT"
    assert not any(p.writable for p in points.values())


@pytest.mark.e2e
def test_dynamic_pdo_warnings(plan: SystemPlan) -> None:
    terminals = {t.slave.name: t for t in plan.masters[0].terminals}
    compact = terminals["Term 5 (EL3104)"]
    assert compact.active_group == "Compact"
    assert any("'Compact'" in w and "'Standard'" in w for w in compact.warnings)
    assert terminals["Term 22 (EL3104)"].active_group == "Standard"
    assert terminals["Term 22 (EL3104)"].warnings == []
    assert terminals["Term 8 (EL1502)"].active_group == "2Ch. Counter"
    assert set(plan.warnings) >= set(compact.warnings)


@pytest.mark.e2e
def test_discovery_is_stable(
    plan: SystemPlan, sim: SimProcess, registry: TerminalRegistry
) -> None:
    again = discover_now(sim, registry)
    first = [(p.key, p.attribute) for t in plan.masters[0].terminals for p in t.points]
    second = [
        (p.key, p.attribute) for t in again.masters[0].terminals for p in t.points
    ]
    assert first == second
    keys = [key for key, _ in first]
    assert len(keys) == len(set(keys))


def test_split_host_port() -> None:
    assert split_host_port("10.0.0.5") == ("10.0.0.5", 48898)
    assert split_host_port("127.0.0.1:4000") == ("127.0.0.1", 4000)


@pytest.mark.e2e
async def test_symbol_version_follows_an_online_change(sim: SimProcess) -> None:
    async with ClientPool(sim.host, sim.tcp_port) as pool:
        device = await pool.get(sim.net_id, 27905)
        before = await read_symbol_version(device)
        sim.add_fault("online_change")
        assert await read_symbol_version(device) == (before + 1) % 256
