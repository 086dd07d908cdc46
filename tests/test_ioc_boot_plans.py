"""Plans without the PLC: a chain file discovered in process, the chain a plan
writes, the per-target cache, and the boot source's order (the PLC, the
configured chain, the cached chain, else wait).

The simulator runs in this process (`SimulatorThread`, loopback sockets) or
is reached without a socket (`twincat.inprocess`); no process is started.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fastcs_ethercat.chain.file import Chain, load_chain, parse_chain
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.boot import boot_source, chain_plan, live_source
from fastcs_ethercat.ioc.chains import (
    cache_path,
    cached_chain,
    chain_data,
    remember,
    write_chain,
)
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.ioc.target import TargetError
from fastcs_ethercat.sim.runner import SimulatorConfig
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry
from fastcs_ethercat.twincat.inprocess import sim_clients
from fastcs_ethercat.twincat.target import SimTarget
from tests.chain_support import played
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import free_port
from tests.sim_thread import SimulatorThread

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"


@pytest.fixture(scope="module")
def registry() -> TerminalRegistry:
    return load_terminals([TERMINALS_DIR])


@pytest.fixture(autouse=True)
def own_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Every test keeps its chains in a cache of its own."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache))
    return cache


@pytest.fixture(scope="module")
def demo_sim() -> Iterator[SimulatorThread]:
    target = SimTarget.from_chain(DEMO_CHAIN, TERMINALS_DIR)
    with SimulatorThread(target, SimulatorConfig(port=0, udp_port=None)) as sim:
        yield sim


def config_for(port: int, **settings: Any) -> IocConfig:
    return IocConfig(
        prefix="BOOT",
        target=f"127.0.0.1:{port}",
        ams_net_id="127.0.0.1.1.1",
        **settings,
    )


def offline(chain: Chain, registry: TerminalRegistry) -> SystemPlan:
    config = config_for(1)
    return asyncio.run(chain_plan(chain, registry, config, "a test"))


def live(port: int, registry: TerminalRegistry) -> SystemPlan:
    async def go() -> SystemPlan:
        plan, connection = await live_source(config_for(port), registry)()
        await connection.pool.close()
        return plan

    return asyncio.run(go())


def shape(plan: SystemPlan) -> list[tuple[object, ...]]:
    """What the tree is built from: slaves, identities, groups, points."""
    return [
        (
            master.name,
            master.net_id,
            terminal.slave.name,
            terminal.slave.address,
            terminal.slave.identity.product_code,
            terminal.slave.identity.revision,
            terminal.slave.type_name,
            terminal.slave.coupler,
            terminal.terminal_type,
            terminal.active_group,
            terminal.oversampling,
            tuple(
                (p.key, p.type_name, p.kind, p.length, p.writable)
                for p in terminal.points
            ),
            tuple((c.index, c.subindex) for c in terminal.coe),
        )
        for master in plan.masters
        for terminal in master.terminals
    ]


def test_a_chain_file_plans_what_discovery_of_that_chain_finds(
    registry: TerminalRegistry, demo_sim: SimulatorThread
) -> None:
    from_file = offline(load_chain(DEMO_CHAIN), registry)
    from_target = live(demo_sim.endpoints.tcp_port, registry)

    assert shape(from_file) == shape(from_target)
    assert from_file.warnings == from_target.warnings
    assert from_file.offline_from == "a test" and not from_target.offline_from
    assert from_file.device_name == ""  # the PLC's own, once it answers


def test_a_plan_writes_the_chain_it_was_discovered_from(
    registry: TerminalRegistry, demo_sim: SimulatorThread, tmp_path: Path
) -> None:
    plan = live(demo_sim.endpoints.tcp_port, registry)
    written = write_chain(plan, "the demo", tmp_path / "dump.yaml")

    assert load_chain(tmp_path / "dump.yaml") == written
    assert played(written, registry) == played(load_chain(DEMO_CHAIN), registry)


def discovered(
    chain: Chain, played: TerminalRegistry, known: TerminalRegistry
) -> SystemPlan:
    """`chain` played from `played`, discovered by an IOC that knows `known`."""
    target = SimTarget(chain, played)

    async def go() -> SystemPlan:
        async with sim_clients(target) as clients:
            return await discover(clients, known, config_for(1), "127.0.0.1.1.1")

    return asyncio.run(go())


def test_a_type_without_yaml_is_kept_by_its_identity(
    registry: TerminalRegistry,
) -> None:
    plan = offline(load_chain(DEMO_CHAIN), registry)
    without = TerminalRegistry(t for t in registry if t.type_name != "EL3202")
    generic = discovered(load_chain(DEMO_CHAIN), registry, without)
    [el3202] = [
        t for t in generic.masters[0].terminals if t.slave.type_name == "EL3202"
    ]
    data = chain_data(generic)
    [entry] = [s for s in data["masters"][0]["slaves"] if s["type"] == "EL3202"]

    assert el3202.terminal_type is None
    assert entry["product_code"] == el3202.slave.identity.product_code
    assert "pdo_group" not in entry
    replayed = offline(parse_chain(_text(data)), without)
    assert shape(replayed)[9][:8] == shape(generic)[9][:8]  # identity, name, place
    assert shape(replayed)[9][11] == ()  # played without process data
    assert shape(plan)[9][11] != ()


def _text(data: dict[str, Any]) -> str:
    from fastcs_ethercat.terminals.yaml_io import dump_yaml

    return dump_yaml(data, header="")


def test_the_cache_keeps_the_last_chain_per_target(
    registry: TerminalRegistry, own_cache: Path
) -> None:
    plan = offline(load_chain(DEMO_CHAIN), registry)
    assert cached_chain("127.0.0.1:1") is None

    remember(plan, "127.0.0.1:1")

    path = cache_path("127.0.0.1:1")
    assert path.is_relative_to(own_cache) and path.is_file()
    kept = cached_chain("127.0.0.1:1")
    assert kept is not None
    assert played(kept, registry) == played(load_chain(DEMO_CHAIN), registry)
    assert cached_chain("127.0.0.1:2") is None


def test_a_broken_cache_is_ignored_with_one_line(
    caplog: pytest.LogCaptureFixture,
) -> None:
    path = cache_path("plc:48898")
    path.parent.mkdir(parents=True)
    path.write_text("masters: 7\n")

    assert cached_chain("plc:48898") is None
    assert [r.levelname for r in caplog.records] == ["WARNING"]


def test_an_unwritable_cache_costs_a_warning_only(
    registry: TerminalRegistry, own_cache: Path, caplog: pytest.LogCaptureFixture
) -> None:
    own_cache.write_text("a file where the cache folder should be")

    remember(offline(load_chain(DEMO_CHAIN), registry), "127.0.0.1:1")

    assert "cannot keep the chain" in caplog.text


def test_boot_serves_the_configured_chain_when_the_plc_does_not_answer(
    registry: TerminalRegistry, caplog: pytest.LogCaptureFixture
) -> None:
    config = config_for(free_port(tcp=True, udp=False), chain=DEMO_CHAIN)

    async def go() -> SystemPlan:
        plan, connection = await boot_source(config, registry)()
        await connection.pool.close()
        return plan

    with caplog.at_level(logging.WARNING):
        plan = asyncio.run(go())

    assert plan.offline_from == f"the chain file {DEMO_CHAIN}"
    assert shape(plan) == shape(offline(load_chain(DEMO_CHAIN), registry))
    assert "connection refused" in caplog.text and "INVALID" in caplog.text


def test_boot_serves_the_cached_chain_without_a_configured_one(
    registry: TerminalRegistry,
) -> None:
    config = config_for(free_port(tcp=True, udp=False))
    remember(offline(load_chain(DEMO_CHAIN), registry), config.target)

    async def go() -> SystemPlan:
        plan, connection = await boot_source(config, registry)()
        await connection.pool.close()
        return plan

    plan = asyncio.run(go())

    assert "kept from the last start" in plan.offline_from
    assert len(plan.masters[0].terminals) == 24


def test_boot_without_any_chain_waits_for_the_plc(
    registry: TerminalRegistry, caplog: pytest.LogCaptureFixture
) -> None:
    port = free_port(tcp=True, udp=False)
    config = config_for(port)
    target = SimTarget.from_chain(DEMO_CHAIN, TERMINALS_DIR)

    async def go() -> SystemPlan:
        boot = asyncio.create_task(boot_source(config, registry)())
        await asyncio.sleep(2.0)
        assert not boot.done()  # waiting, not exiting
        with SimulatorThread(target, SimulatorConfig(port=port, udp_port=None)):
            plan, connection = await asyncio.wait_for(boot, 30)
            await connection.pool.close()
        return plan

    with caplog.at_level(logging.INFO):
        plan = asyncio.run(go())

    assert not plan.offline_from and len(plan.masters[0].terminals) == 24
    waits = [r for r in caplog.records if "nothing to serve" in r.getMessage()]
    assert len(waits) == 1  # at most one line per 10 s


def test_list_pvs_without_the_plc_fails_in_one_line(
    registry: TerminalRegistry,
) -> None:
    config = config_for(free_port(tcp=True, udp=False))

    with pytest.raises(TargetError, match="connection refused"):
        asyncio.run(live_source(config, registry)())


def test_a_configured_chain_that_does_not_load_stops_every_start(
    registry: TerminalRegistry, demo_sim: SimulatorThread, tmp_path: Path
) -> None:
    """Checked while the PLC answers too: not first found on the day it is away."""
    broken = tmp_path / "rack.yaml"
    broken.write_text(DEMO_CHAIN.read_text().replace("type: EL3602", "type: EL9999"))
    config = config_for(demo_sim.endpoints.tcp_port, chain=broken)

    with pytest.raises(UserError, match=r"rack.yaml:\d+:\d+: .*'EL9999'"):
        asyncio.run(boot_source(config, registry)())


def test_a_cached_chain_of_types_no_longer_known_is_ignored(
    registry: TerminalRegistry, caplog: pytest.LogCaptureFixture
) -> None:
    config = config_for(free_port(tcp=True, udp=False))
    remember(offline(load_chain(DEMO_CHAIN), registry), config.target)
    without = TerminalRegistry(t for t in registry if t.type_name != "EL3602")

    with pytest.raises(TimeoutError):  # waits for the PLC instead
        asyncio.run(asyncio.wait_for(boot_source(config, without)(), 1.0))
    assert "ignoring the cached chain" in caplog.text
