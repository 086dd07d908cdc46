"""Terminals whose revision has no YAML: served from the nearest revision of
their product code, matched to the live table by name.

The rack (`CHAIN`) runs older and newer revisions of the DLS types than the
IOC's YAML: the simulator plays each revision from the YAML generated from
that revision's ESI (`tests.revisions_support`, `sim --revisions`), so its
symbol tables are those of the revisions it reports. Nothing falls back to
the generic controller: outputs stay writable, CoE is served, and one
warning per terminal names both revisions and what the live table lacks.
"""

from __future__ import annotations

import asyncio
import re
import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.chain.file import parse_chain
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.discovery import discover
from fastcs_ethercat.ioc.plan import SystemPlan, TerminalPlan
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals.loader import load_terminals
from fastcs_ethercat.twincat.inprocess import sim_clients
from fastcs_ethercat.twincat.resolve import load_revisions
from fastcs_ethercat.twincat.target import SimTarget
from tests.conftest import TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    IocProcess,
    caget,
    ioc_env,
    list_pvs,
    new_token,
    start_ioc,
    terminals_with_coe,
    wait_for,
    write_ioc_config,
)
from tests.revisions_support import OLDER, replace_with_revisions, write_revisions

CHAIN = """
masters:
- slaves:
  - type: EK1100
  - type: EL2024            # Term 2: runs 0x00130000, the IOC knows 0x00100000
  - type: EL4134            # Term 3: runs an older revision
    revision: 0x03f80000
  - type: EL3104            # Term 4: older; CoE selected in the IOC's YAML
    revision: 0x00100000
    pdo_group: Standard
  - type: EL4732            # Term 5: older, with other symbols altogether
    revision: 0x00000001
  - type: EL1502            # Term 6: older, with other PDO group names
    revision: 0x00100000
"""
IOC_REVISIONS = {"EL2024": 0x00100000}
"""Types whose YAML in the IOC is older than what the rack runs."""
REVISION_LINE = re.compile(
    r"(Term \d \(\S+\)): revision (0x[0-9a-f]{8}) has no YAML; "
    r"served from (\S+) revision (0x[0-9a-f]{8})"
)


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """(chain file, the simulator's revisions, the IOC's terminal YAML)."""
    root = tmp_path_factory.mktemp("revisions")
    chain = root / "chain.yaml"
    chain.write_text(CHAIN)
    shelf = write_revisions(root / "shelf", OLDER)
    ioc_terminals = replace_with_revisions(
        terminals_with_coe(root / "ioc-terminals"), IOC_REVISIONS
    )
    return chain, shelf, ioc_terminals


@pytest.fixture(scope="module")
def plan(folders: tuple[Path, Path, Path]) -> SystemPlan:
    chain, shelf, ioc_terminals = folders
    target = SimTarget(
        parse_chain(chain.read_text()),
        load_terminals([TERMINALS_DIR]),
        revisions=load_revisions([shelf]),
    )
    assert target.notes == []  # every revision played from its own YAML
    registry = load_terminals([ioc_terminals])

    async def go() -> SystemPlan:
        async with sim_clients(target) as clients:
            config = IocConfig(prefix="REV", target="127.0.0.1")
            return await discover(clients, registry, config, str(target.system_net_id))

    return asyncio.run(go())


def terminal(plan: SystemPlan, number: int) -> TerminalPlan:
    [found] = [
        t
        for t in plan.masters[0].terminals
        if t.slave.name.startswith(f"Term {number} ")
    ]
    return found


def test_every_terminal_is_served_from_a_yaml_of_its_product_code(
    plan: SystemPlan,
) -> None:
    terminals = plan.masters[0].terminals

    assert all(t.terminal_type is not None for t in terminals)
    assert [t.exact_revision for t in terminals] == [True] + [False] * 5


def test_one_warning_per_terminal_names_both_revisions(plan: SystemPlan) -> None:
    named = [REVISION_LINE.match(w) for w in plan.warnings]

    assert all(named), plan.warnings
    assert [m.groups() for m in named if m] == [
        ("Term 2 (EL2024)", "0x00130000", "EL2024", "0x00100000"),  # newer
        ("Term 3 (EL4134)", "0x03f80000", "EL4134", "0x03fa0000"),  # older
        ("Term 4 (EL3104)", "0x00100000", "EL3104", "0x00110000"),
        ("Term 5 (EL4732)", "0x00000001", "EL4732", "0x00040000"),
        ("Term 6 (EL1502)", "0x00100000", "EL1502", "0x00160000"),
    ]


def test_what_the_live_table_lacks_is_dropped_and_said(plan: SystemPlan) -> None:
    el4732 = terminal(plan, 5)
    [warning] = [w for w in plan.warnings if w.startswith("Term 5 ")]

    assert "5 selected symbols not on the target, dropped: 'StartTimeNextOutput'" in (
        warning
    )
    assert "3 live symbols it does not describe, not served" in warning
    assert {p.attribute for p in el4732.points} == {"wc_state", "input_toggle"}


def test_outputs_coe_and_groups_follow_the_live_table(plan: SystemPlan) -> None:
    el4134, el3104, el1502 = terminal(plan, 3), terminal(plan, 4), terminal(plan, 6)

    assert [p.symbol for p in el4134.points if p.writable] == [
        f"Term 3 (EL4134).AO Output Channel {n}" for n in (1, 2, 3, 4)
    ]
    assert any(p.writable for p in terminal(plan, 2).points)
    assert el3104.active_group == "Standard" and el3104.coe
    assert el1502.active_group is not None and el1502.points


@pytest.mark.e2e
def test_the_ioc_writes_outputs_and_reads_coe_of_other_revisions(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    chain, shelf, ioc_terminals = folders
    token = new_token()
    env = ioc_env(token)
    prefix = f"REV{token[:6].upper()}"
    with SimProcess(chain, revisions=[shelf], env=env) as sim:
        config = write_ioc_config(
            tmp_path,
            prefix,
            sim.pyads_ip,
            sim.net_id,
            terminal_dirs=[str(ioc_terminals)],
        )
        pvs = _pv_list(config, env)
        ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], prefix, env, token)
        try:
            ioc.wait_for_line("ioc ready", 90)
            _check_outputs(ioc, sim, pvs)
            _check_coe(ioc, pvs)
            _check_types(ioc, pvs)
        finally:
            ioc.stop()
    warnings = [line for line in ioc.output if "has no YAML" in line]
    assert len(warnings) == 5, "".join(ioc.output[-40:])
    assert all(REVISION_LINE.search(line) for line in warnings)


def _pv_list(config: Path, env: dict[str, str]) -> dict[str, tuple[str, str]]:
    """PV name -> (access, source), from `ioc --list-pvs`."""
    return {name: (access, source) for name, access, _, source in list_pvs(config, env)}


def _named(pvs: dict[str, tuple[str, str]], access: str, source: str) -> str:
    [name] = [n for n, (a, s) in pvs.items() if a == access and s == source]
    return name


def _check_outputs(
    ioc: IocProcess, sim: SimProcess, pvs: dict[str, tuple[str, str]]
) -> None:
    for symbol, value, counts in (
        ("Term 3 (EL4134).AO Output Channel 2", 2.5, 8192),  # volts in, counts out
        ("Term 2 (EL2024).Channel 3", 1, 1),
    ):
        pv = _named(pvs, "rw", symbol)
        ioc.tool("caput", "-c", pv, str(value))
        assert wait_for(lambda s=symbol, c=counts: sim.get_symbol(s) == c, 10), symbol


def _check_coe(ioc: IocProcess, pvs: dict[str, tuple[str, str]]) -> None:
    coe = [
        n
        for n, (access, source) in pvs.items()
        if access == "r" and source.startswith("CoE:8000:")
    ]
    assert coe
    shown = wait_for(
        lambda: all(
            "INVALID" not in line for line in ioc.tool("caget", "-a", *coe).splitlines()
        ),
        30,
    )
    assert shown, ioc.tool("caget", "-a", *coe)


def _check_types(ioc: IocProcess, pvs: dict[str, tuple[str, str]]) -> None:
    """`Type` shows what the master reports (the chain's type names)."""
    types = [n for n, (_, source) in pvs.items() if n.endswith(":Type")]
    shown = set(caget(ioc, "-S", *types).values())
    assert {"EL2024", "EL4134", "EL3104", "EL4732", "EL1502"} <= shown


def test_the_revision_shelf_is_where_the_simulator_finds_revisions(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    chain, shelf, _ = folders
    without = SimTarget(parse_chain(chain.read_text()), load_terminals([TERMINALS_DIR]))
    twice = tmp_path / "twice"
    shutil.copytree(shelf, twice)
    shutil.copy(
        shelf / "EL4134-0x03f80000.yaml", twice / "EL4134-again-0x03f80000.yaml"
    )

    assert len(without.notes) == 4  # the shipped revision played, and said so
    assert "no YAML of EL4134 revision 0x03f80000" in without.notes[0]
    with pytest.raises(Exception, match="revision 0x03f80000 is described twice"):
        load_revisions([twice])
