"""Symbol resolution: live tables + YAML -> points (real simulator, real pyads).

The chain has two masters, dynamic PDOs (EL3104 Compact, EL1502's second
group), an oversampled EL3702 (4 samples, the YAML says 10) and an EL3602
whose YAML the IOC does not get (a copy of terminals/ without it).
"""

from __future__ import annotations

import asyncio
import dataclasses
import shutil
from collections.abc import Iterator

import pytest

from fastcs_ethercat.ads.client import SymbolTables
from fastcs_ethercat.ads.constants import device_port
from fastcs_ethercat.ads.ethercat import SlaveIdentity
from fastcs_ethercat.ads.symbols import AdsSymbolEntry
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.plan import (
    MasterPlan,
    PointKind,
    SlaveInfo,
    SystemPlan,
    TerminalPlan,
)
from fastcs_ethercat.ioc.resolve import (
    Resolver,
    coe_points,
    group_symbols,
    resolve_master,
    snake_case,
)
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals import load_terminals
from fastcs_ethercat.terminals.registry import TerminalRegistry
from fastcs_ethercat.twincat.inprocess import sim_clients
from tests.conftest import TERMINALS_DIR
from tests.test_sim_model_support import demo_target

CHAIN = """\
system:
  net_id: 127.0.0.1.1.1
  task_cycle_ms: 10
masters:
- name: Device 1 (EtherCAT)
  slaves:
  - type: EK1100
  - type: EL3104
    pdo_group: Compact
  - type: EL3602
  - type: EL2024
  - type: EL3702
    oversampling: 4
- name: Device 2 (EtherCAT)
  slaves:
  - type: EK1100
  - type: EL1502
    pdo_group: 2Ch. Counter
  - type: EL3104
"""
UNKNOWN = "EL3602"


@pytest.fixture(scope="module")
def registry(tmp_path_factory: pytest.TempPathFactory) -> TerminalRegistry:
    """Every terminal YAML but the EL3602's."""
    folder = tmp_path_factory.mktemp("terminals")
    for path in TERMINALS_DIR.glob("*.yaml"):
        if path.stem != UNKNOWN:
            shutil.copy(path, folder / path.name)
    return load_terminals([folder])


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimProcess]:
    chain = tmp_path_factory.mktemp("chain") / "chain.yaml"
    chain.write_text(CHAIN)
    with SimProcess(chain, terminals=TERMINALS_DIR) as process:
        yield process


async def _discover_with_tables(
    sim: SimProcess, registry: TerminalRegistry
) -> tuple[SystemPlan, dict[int, SymbolTables]]:
    config = IocConfig(prefix="TEST", target=sim.pyads_ip, ams_net_id=sim.net_id)
    async with ClientPool(config.target_host, config.target_port) as pool:
        plan = await discover(pool, registry, config)
        tables = {
            m.device_id: await (await pool(sim.net_id, m.symbol_port)).upload_symbols()
            for m in plan.masters
        }
    return plan, tables


@pytest.fixture(scope="module")
def resolved(
    sim: SimProcess, registry: TerminalRegistry
) -> tuple[SystemPlan, dict[int, SymbolTables]]:
    return asyncio.run(_discover_with_tables(sim, registry))


@pytest.fixture(scope="module")
def plan(resolved: tuple[SystemPlan, dict[int, SymbolTables]]) -> SystemPlan:
    return resolved[0]


def terminal(plan: SystemPlan, device: int, name: str) -> TerminalPlan:
    master = next(m for m in plan.masters if m.device_id == device)
    return next(t for t in master.terminals if t.slave.name == name)


@pytest.mark.e2e
def test_two_masters(plan: SystemPlan) -> None:
    masters = [(m.device_id, m.name, m.net_id, m.symbol_port) for m in plan.masters]
    assert masters == [
        (1, "Device 1 (EtherCAT)", "127.0.0.1.2.1", 27905),
        (2, "Device 2 (EtherCAT)", "127.0.0.1.3.1", 27906),
    ]
    assert [len(m.terminals) for m in plan.masters] == [5, 3]
    for master in plan.masters:
        assert {p.symbol for p in master.master_points} >= {
            f"{master.name}.Inputs.SlaveCount",
            f"{master.name}.Outputs.DevCtrl",
        }


@pytest.mark.e2e
def test_compact_group_detected_with_warning(plan: SystemPlan) -> None:
    compact = terminal(plan, 1, "Term 2 (EL3104)")
    assert compact.active_group == "Compact"
    assert any("Compact" in w and "Standard" in w for w in compact.warnings)
    points = {p.attribute: p for p in compact.points}
    assert set(points) == {
        *(f"ai_compact_channel_{n}" for n in range(1, 5)),
        "wc_state",
        "input_toggle",
    }
    value = points["ai_compact_channel_3"]
    assert (value.kind, value.type_name, value.byte_size) == (
        PointKind.SCALAR,
        "INT",
        2,
    )
    assert value.symbol == "Term 2 (EL3104).AI Compact Channel 3"
    assert not value.writable


@pytest.mark.e2e
def test_standard_group_members_and_status_bits(plan: SystemPlan) -> None:
    standard = terminal(plan, 2, "Term 8 (EL3104)")
    assert standard.active_group == "Standard"
    assert standard.warnings == []
    points = {p.attribute: p for p in standard.points}
    value = points["ai_standard_channel_2_value"]
    overrange = points["ai_standard_channel_2_status_overrange"]
    limit = points["ai_standard_channel_2_status_limit_1"]
    assert (value.kind, value.type_name, value.byte_size) == (
        PointKind.SCALAR,
        "INT",
        2,
    )
    # The status word is read once (2 bytes at the symbol's start), bits within.
    assert overrange.index_offset == value.index_offset - 2
    assert (overrange.kind, overrange.byte_size, overrange.bit_offset) == (
        PointKind.BIT,
        2,
        1,
    )
    assert (limit.kind, limit.bit_offset, limit.bit_size) == (PointKind.BITS, 2, 2)
    assert overrange.symbol.endswith("AI Standard Channel 2.Status.Overrange")


@pytest.mark.e2e
def test_counter_in_its_second_group(plan: SystemPlan) -> None:
    counter = terminal(plan, 2, "Term 7 (EL1502)")
    assert counter.active_group == "2Ch. Counter"
    assert counter.warnings
    points = {p.attribute: p for p in counter.points}
    assert points["cnt_inputs_channel_2_counter_value"].type_name == "UDINT"
    control = points["cnt_outputs_channel_1_control_set_counter"]
    assert control.writable and control.kind is PointKind.BIT
    assert points["cnt_outputs_channel_1_set_counter_value"].writable


@pytest.mark.e2e
def test_oversampling_length_from_the_live_table(plan: SystemPlan) -> None:
    oversampled = terminal(plan, 1, "Term 5 (EL3702)")
    samples = [p for p in oversampled.points if p.kind is PointKind.ARRAY]
    assert samples
    for point in samples:
        assert (point.length, point.type_name, point.byte_size) == (4, "INT", 8)


@pytest.mark.e2e
def test_unknown_terminal_gets_a_generic_plan(
    resolved: tuple[SystemPlan, dict[int, SymbolTables]],
) -> None:
    plan, tables = resolved
    generic = terminal(plan, 1, "Term 3 (EL3602)")
    assert generic.terminal_type is None
    assert generic.warnings and "no terminal YAML" in generic.warnings[0]
    assert not any(p.writable for p in generic.points)
    live = {e.name for e in tables[1].symbols if e.name.startswith("Term 3 (EL3602).")}
    served = {p.symbol for p in generic.points}
    for name in live:
        assert name in served or any(s.startswith(name + ".") for s in served)
    attributes = {p.attribute for p in generic.points}
    assert {"wc_state", "input_toggle", "ai_inputs_channel_1_value"} <= attributes
    assert len(attributes) == len(generic.points)


@pytest.mark.e2e
def test_points_sit_where_the_live_table_says(
    resolved: tuple[SystemPlan, dict[int, SymbolTables]],
) -> None:
    plan, tables = resolved
    for master in plan.masters:
        entries = {e.name: e for e in tables[master.device_id].symbols}
        for plan_terminal in master.terminals:
            for point in plan_terminal.points:
                entry = entries.get(point.symbol) or next(
                    e
                    for name, e in entries.items()
                    if point.symbol.startswith(name + ".")
                )
                assert point.index_group == entry.index_group
                assert (
                    entry.index_offset
                    <= point.index_offset
                    < entry.index_offset + max(entry.size, 1)
                )


@pytest.mark.e2e
def test_attributes_unique_per_terminal(plan: SystemPlan) -> None:
    for master in plan.masters:
        for plan_terminal in master.terminals:
            names = [p.attribute for p in plan_terminal.points]
            assert len(names) == len(set(names)), plan_terminal.slave.name
            assert all(name == snake_case(name) for name in names)


@pytest.mark.e2e
def test_yaml_bit_offsets_when_the_type_is_not_listed(
    plan: SystemPlan, registry: TerminalRegistry
) -> None:
    standard = terminal(plan, 2, "Term 8 (EL3104)")
    value = next(p for p in standard.points if p.attribute.endswith("channel_1_value"))
    entry = AdsSymbolEntry(
        name="Term 8 (EL3104).AI Standard Channel 1",
        index_group=value.index_group,
        index_offset=value.index_offset - 2,
        size=4,
        data_type=65,
        type_name="AI Standard Channel 1_TYPE",
    )
    fallback = Resolver({}, registry).terminal("M", standard.slave, [entry])
    points = {p.attribute: p for p in fallback.points}
    assert points["ai_standard_channel_1_value"].index_offset == value.index_offset
    toggle = points["ai_standard_channel_1_status_txpdo_toggle"]
    assert (toggle.kind, toggle.index_offset, toggle.bit_offset) == (
        PointKind.BIT,
        value.index_offset - 1,
        7,
    )


@pytest.mark.e2e
def test_terminals_of_a_type_share_the_work_not_the_points(
    resolved: tuple[SystemPlan, dict[int, SymbolTables]], registry: TerminalRegistry
) -> None:
    """One `Resolver` works a type out once per live layout: every terminal
    still gets what it gets resolved alone, at its own names and addresses
    (the same layout elsewhere, another group, a symbol missing)."""
    plan, tables = resolved
    types = {t.name: t for table in tables.values() for t in table.data_types}
    standard_slave = terminal(plan, 2, "Term 8 (EL3104)").slave
    compact_slave = terminal(plan, 1, "Term 2 (EL3104)").slave
    standard = group_symbols(tables[2].symbols)[standard_slave.name]
    compact = group_symbols(tables[1].symbols)[compact_slave.name]

    def moved(
        name: str, shift: int, dropped: str = ""
    ) -> tuple[SlaveInfo, list[AdsSymbolEntry]]:
        entries = [
            dataclasses.replace(
                e,
                name=name + e.name.removeprefix(standard_slave.name),
                index_offset=e.index_offset + shift,
            )
            for e in standard
            if not dropped or not e.name.endswith(dropped)
        ]
        return dataclasses.replace(standard_slave, name=name), entries

    rack = [
        (standard_slave, standard),
        (compact_slave, compact),
        moved("Term 20 (EL3104)", 100),
        moved("Term 21 (EL3104)", 200, dropped=".AI Standard Channel 2"),
        (standard_slave, standard),
    ]
    resolver = Resolver(types, registry)
    shared = [resolver.terminal("M", slave, entries) for slave, entries in rack]
    alone = [
        Resolver(types, registry).terminal("M", slave, entries)
        for slave, entries in rack
    ]
    assert shared == alone
    first, _, same_layout, one_missing, again = shared
    assert again == first
    assert [p.index_offset + 100 for p in first.points] == [
        p.index_offset for p in same_layout.points
    ]
    assert all(p.symbol.startswith("Term 20 (EL3104).") for p in same_layout.points)
    assert len(one_missing.points) < len(first.points)
    assert "dropped: 'AI Standard Channel 2'" in one_missing.warnings[-1]


def test_coe_points_of_selected_objects(registry: TerminalRegistry) -> None:
    el3104 = registry.get("EL3104").terminal.model_copy(deep=True)
    shipped = coe_points(el3104)  # the one sub-index the shipped file selects
    assert [(p.index, p.subindex) for p in shipped] == [(0x8000, 0x06)]
    settings = next(o for o in el3104.coe_objects if o.index == 0x8000)
    for sub in settings.sub_items:
        sub.selected = True
    points = {p.attribute: p for p in coe_points(el3104)}
    gain = points["ai_settings_8000_user_calibration_gain"]
    assert (gain.index, gain.subindex, gain.type_name, gain.writable) == (
        0x8000,
        0x18,
        "INT",
        True,
    )
    assert dict(points["ai_settings_8000_presentation"].enum_texts)[1] == "Unsigned"


def test_helpers() -> None:
    assert snake_case("Frm0WcState") == "frm0_wc_state"
    assert snake_case("RMB Value (INT32)") == "rmb_value_int32"
    assert snake_case("1st") == "n1st"
    entry = AdsSymbolEntry("Term 1 (EL1014).Channel 1", 0xF031, 0, 1, 33, "BIT")
    assert group_symbols([entry]) == {"Term 1 (EL1014)": [entry]}
    unknown = SlaveInfo(1001, "Term 1 (X)", SlaveIdentity(2, 0x1234, 1))
    assert Resolver({}, load_terminals([])).terminal("M", unknown, []).points == []


@pytest.mark.e2e
def test_points_carry_units_severities_and_descriptions(plan: SystemPlan) -> None:
    """What the ESI names and DScale say, on the live points."""
    compact = {p.attribute: p for p in terminal(plan, 1, "Term 2 (EL3104)").points}
    standard = {p.attribute: p for p in terminal(plan, 2, "Term 8 (EL3104)").points}
    samples = [
        p for p in terminal(plan, 1, "Term 5 (EL3702)").points
        if p.kind is PointKind.ARRAY
    ]  # fmt: skip
    generic = {p.attribute: p for p in terminal(plan, 1, "Term 3 (EL3602)").points}
    value = standard["ai_standard_channel_2_value"]
    error = standard["ai_standard_channel_2_status_error"]
    overrange = standard["ai_standard_channel_2_status_overrange"]
    toggle = standard["ai_standard_channel_2_status_txpdo_toggle"]

    one_entry = compact["ai_compact_channel_1"].scaling  # a one-entry PDO too
    assert one_entry is not None and one_entry.unit == "V"
    assert value.scaling is not None and value.scaling.converts
    assert value.scaling.scale == pytest.approx(10 / 32767)
    assert value.description == "EL3104 AI Standard Ch2 Value"
    assert (error.severity, overrange.severity, toggle.severity) == (2, 1, 0)
    assert error.scaling is None
    assert error.description == "EL3104 AI Standard Ch2 Error"
    assert standard["wc_state"].severity == 2
    assert standard["input_toggle"].severity == 0
    assert all(p.scaling is not None and p.scaling.unit == "V" for p in samples)
    assert generic["ai_inputs_channel_1_value"].scaling is None  # no YAML: raw
    assert generic["ai_inputs_channel_1_error"].severity == 2  # names still count
    assert (
        generic["ai_inputs_channel_1_value"].description == "EL3602 AI Inputs Ch1 Value"
    )


MASTER = "Device 1 (EtherCAT)"


async def _demo_tables() -> SymbolTables:
    """The demo chain's device-port tables, from the simulator's model."""
    target = demo_target()
    async with sim_clients(target) as clients:
        client = await clients(str(target.system_net_id), device_port(1))
        return await client.upload_symbols()


def _bare(tables: SymbolTables, one_by_one: bool) -> SymbolTables:
    """The master's own symbols without the device's name: `Inputs` (a
    structure), or each member a symbol of its own (`Inputs.Frm0State`)."""
    types = {t.name: t for t in tables.data_types}
    symbols: list[AdsSymbolEntry] = []
    for entry in tables.symbols:
        if not entry.name.startswith(f"{MASTER}."):
            symbols.append(entry)
            continue
        bare = entry.name.removeprefix(f"{MASTER}.")
        if not one_by_one:
            symbols.append(dataclasses.replace(entry, name=bare))
            continue
        for member in types[entry.type_name].sub_items:
            symbols.append(
                dataclasses.replace(
                    entry,
                    name=f"{bare}.{member.name}",
                    index_offset=entry.index_offset + member.offset,
                    size=member.size,
                    data_type=member.data_type,
                    type_name=member.type_name,
                )
            )
    return dataclasses.replace(tables, symbols=symbols)


def _master_points(tables: SymbolTables) -> dict[str, tuple[str, int, int, str]]:
    master = MasterPlan(1, MASTER, "127.0.0.1.2.1", device_port(1))
    config = IocConfig(prefix="TEST", target="127.0.0.1")
    resolve_master(master, [], tables, load_terminals([TERMINALS_DIR]), config)
    return {
        p.attribute: (p.symbol.removeprefix(f"{MASTER}."), p.index_offset,
                      p.byte_size, p.type_name)
        for p in master.master_points
    }  # fmt: skip


@pytest.mark.parametrize("one_by_one", [False, True])
async def test_bare_master_symbols_give_the_same_master_points(
    one_by_one: bool,
) -> None:
    """The simulator serves the master's symbols as a real rack's dump shows
    them (`Device 1 (EtherCAT).Inputs.Frm0State`); a target serving them
    bare, as the facts file's section 7 lists them (`Inputs.Frm0State`),
    gets the same master points, read at the same place."""
    tables = await _demo_tables()
    prefixed = _master_points(tables)
    bare = _master_points(_bare(tables, one_by_one))

    assert {"frm0_state", "slave_count", "dev_ctrl"} <= prefixed.keys()
    assert prefixed["slave_count"][0] == "Inputs.SlaveCount"
    assert bare == prefixed
