"""The parts of `init` that decide: what changed on the rack, which YAML
describes a type and revision, the group it selects, the files' names and
text, and the summary of a whole run (`run_init` from a chain file, played
in this process as the IOC plays one: no simulator, no network). (The
command against the simulator: `test_init.py`.)"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
import yaml

from fastcs_ethercat.ads.ethercat import SlaveIdentity
from fastcs_ethercat.chain.file import load_chain
from fastcs_ethercat.cli.terminals import select_group_command
from fastcs_ethercat.commission import layout
from fastcs_ethercat.commission.choices import running_choice, with_running
from fastcs_ethercat.commission.rack import (
    ChangeKind,
    RackSlave,
    rack_changes,
    rack_slaves,
)
from fastcs_ethercat.commission.run import InitRequest, Outcome, run_init
from fastcs_ethercat.commission.sources import (
    Describer,
    Origin,
    discovery_registry,
    file_names,
)
from fastcs_ethercat.commission.summary import summary_lines
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import build_catalog
from fastcs_ethercat.ioc.app import list_pvs
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.ioc.naming import MAX_PV_LENGTH
from fastcs_ethercat.ioc.plan import Point, PointKind, SlaveInfo, TerminalPlan
from fastcs_ethercat.terminals.loader import load_terminals
from tests.conftest import ESI_SUBSET, TERMINALS_DIR

BECKHOFF = 2
EL1014 = 0x03F63052
EL3102 = 0x0C1E3052
EL9999 = 0x270F3052


BASE = RackSlave("Device 1 (EtherCAT)", 0, "", "EL2024", 0x00130000, None, None)


def slave(name: str, position: int, type_name: str = "EL2024", **kw: Any) -> RackSlave:
    return replace(BASE, name=name, position=position, type_name=type_name, **kw)


def test_rack_changes_name_each_kind_of_change() -> None:
    before = [
        slave("Term 1 (EL2024)", 0),
        slave("Term 2 (EL2024)", 1),
        slave("Term 3 (EL3104)", 2, "EL3104", pdo_group="Standard"),
        slave("Term 4 (EL3702)", 3, "EL3702", oversampling=10),
        slave("Term 5 (EL2024)", 4),
    ]
    after = [
        slave("Term 1 (EL2024)", 0, revision=0x00120000),
        slave("Term 9 (EL2124)", 1, "EL2124"),
        slave("Term 3 (EL3104)", 2, "EL3104", pdo_group="Compact"),
        slave("Term 4 (EL3702)", 3, "EL3702", oversampling=5),
        slave("Term 6 (EL1014)", 4, "EL1014"),
        slave("Term 7 (EL1014)", 5, "EL1014"),
    ]

    changes = rack_changes(before, after)

    assert [change.line() for change in changes] == [
        "other revision: Term 1 (EL2024): EL2024 revision 0x00130000 -> "
        "EL2024 revision 0x00120000",
        "swapped: Term 2 (EL2024) (EL2024 revision 0x00130000) -> Term 9 (EL2124) "
        "(EL2124 revision 0x00130000) on Device 1 (EtherCAT)",
        "other PDO group: Term 3 (EL3104): 'Standard' -> 'Compact'",
        "other oversampling: Term 4 (EL3702): 10 -> 5",
        "swapped: Term 5 (EL2024) (EL2024 revision 0x00130000) -> Term 6 (EL1014) "
        "(EL1014 revision 0x00130000) on Device 1 (EtherCAT)",
        "added: Term 7 (EL1014) (EL1014 revision 0x00130000) on Device 1 (EtherCAT)",
    ]
    assert rack_changes(after, after) == []
    [removed] = rack_changes(before, before[1:])
    assert (removed.kind, removed.slave.name) == (ChangeKind.REMOVED, "Term 1 (EL2024)")


def terminal_plan(
    name: str, product: int, revision: int, *, typed: str | None = None,
    group: str | None = None, points: int = 0,
) -> TerminalPlan:  # fmt: skip
    info = SlaveInfo(
        address=1001,
        name=name,
        identity=SlaveIdentity(BECKHOFF, product, revision),
        type_name=name.rsplit("(", 1)[-1].rstrip(")"),
    )
    plan = TerminalPlan(slave=info, terminal_type=typed, active_group=group)
    plan.points = [
        Point(f"k{n}", f"s{n}", f"a{n}", "BIT", PointKind.BIT, 0, 0, 1)
        for n in range(points)
    ]
    return plan


@pytest.fixture(scope="module")
def describer() -> Describer:
    shipped = list(load_terminals([TERMINALS_DIR]))
    return Describer([], shipped, lambda: build_catalog(ESI_SUBSET))


def test_a_revision_is_described_by_shipped_yaml_else_its_own_esi_else_the_nearest(
    describer: Describer,
) -> None:
    shipped = describer.describe(
        (BECKHOFF, EL1014, 0x00130000), [terminal_plan("Term 2 (EL1014)", EL1014, 0)]
    )
    older = describer.describe(
        (BECKHOFF, EL1014, 0x00120000), [terminal_plan("Term 3 (EL1014)", EL1014, 0)]
    )
    newer = describer.describe(
        (BECKHOFF, EL1014, 0x00190000), [terminal_plan("Term 4 (EL1014)", EL1014, 0)]
    )

    assert (shipped.origin, shipped.text is not None) == (Origin.SHIPPED, True)
    assert older.origin is Origin.GENERATED
    assert older.terminal is not None
    assert older.terminal.identity.revision_number == 0x00120000
    assert older.source.endswith("Beckhoff EL1xxx.xml:215")
    assert newer.origin is Origin.NEAREST_YAML  # the shipped 0x00130000's
    assert newer.terminal is not None
    assert newer.terminal.identity.revision_number == 0x00130000
    assert newer.source.endswith("EL1014.yaml")
    esi_only = Describer([], [], lambda: build_catalog(ESI_SUBSET)).describe(
        (BECKHOFF, EL1014, 0x00190000), [terminal_plan("Term 4 (EL1014)", EL1014, 0)]
    )
    assert esi_only.origin is Origin.NEAREST
    assert esi_only.terminal is not None
    assert esi_only.terminal.identity.revision_number == 0x00130000
    assert "Beckhoff EL1xxx.xml:" in esi_only.source


def test_a_type_nothing_describes_is_refused_only_with_process_data(
    describer: Describer,
) -> None:
    identity = (BECKHOFF, EL9999, 0x00100000)
    quiet = describer.describe(identity, [terminal_plan("Term 5 (EL9999)", EL9999, 0)])
    assert quiet.origin is Origin.NONE

    with pytest.raises(UserError) as refused:
        describer.describe(
            identity, [terminal_plan("Term 5 (EL9999)", EL9999, 0, points=2)]
        )
    assert str(refused.value).startswith(
        "esi: no ESI description and no terminal YAML of EL9999 (product code "
        "0x270f3052, revision 0x00100000; 1 on the rack, first Term 5 (EL9999))"
    )


def test_without_esi_of_the_type_a_yaml_of_another_revision_serves_it() -> None:
    shipped = list(load_terminals([TERMINALS_DIR]))
    empty = Describer([], shipped, lambda: build_catalog([]))

    found = empty.describe(
        (BECKHOFF, EL1014, 0x00120000), [terminal_plan("Term 3 (EL1014)", EL1014, 0)]
    )

    assert found.origin is Origin.OTHER_YAML
    assert found.source.endswith("EL1014.yaml")


def test_the_revision_most_terminals_run_gets_the_plain_file_name(
    describer: Describer,
) -> None:
    one = describer.describe(
        (BECKHOFF, EL1014, 0x00120000), [terminal_plan("Term 2 (EL1014)", EL1014, 0)]
    )
    many = describer.describe(
        (BECKHOFF, EL1014, 0x00110000),
        [terminal_plan(f"Term {n} (EL1014)", EL1014, 0) for n in (3, 4)],
    )

    file_names([one, many])

    assert (one.file_name, many.file_name) == ("EL1014_r00120000.yaml", "EL1014.yaml")


def test_yaml_already_in_dir_comes_before_the_shipped_one(tmp_path: Path) -> None:
    (tmp_path / "EL1014.yaml").write_bytes((TERMINALS_DIR / "EL1014.yaml").read_bytes())
    kept = list(load_terminals([tmp_path], use_cache=False))
    shipped = list(load_terminals([TERMINALS_DIR]))

    registry = discovery_registry(kept, shipped)
    found = Describer(kept, shipped, lambda: build_catalog([])).describe(
        (BECKHOFF, EL1014, 0x00130000), [terminal_plan("Term 2 (EL1014)", EL1014, 0)]
    )

    assert len(registry) == len(shipped)
    match = registry.lookup(EL1014, 0x00130000)
    assert match is not None and match.path == tmp_path / "EL1014.yaml"
    assert (found.origin, found.file_name) == (Origin.KEPT, "EL1014.yaml")


def test_the_group_most_terminals_run_is_selected_and_a_mix_is_named(
    describer: Describer,
) -> None:
    described = describer.describe(
        (BECKHOFF, EL3102, 0x00110000), [terminal_plan("Term 9 (EL3102)", EL3102, 0)]
    )
    terminal = described.terminal
    assert terminal is not None and terminal.selected_pdo_group == "Standard"
    slaves = [
        terminal_plan(f"Term {n} (EL3102)", EL3102, 0x00110000, group=group)
        for n, group in ((1, "Compact"), (2, "Compact"), (3, "Standard"))
    ]

    running = running_choice("EL3102", terminal, slaves)
    chosen = with_running(terminal, running)

    assert running.group == "Compact"
    assert chosen.selected_pdo_group == "Compact"
    [decision] = running.decisions
    assert decision.startswith(
        "EL3102: terminals run different PDO groups ('Compact' on 2, 'Standard' on 1)"
    )
    tie = running_choice("EL3102", terminal, slaves[1:])
    assert tie.group == "Standard"  # the YAML's own choice on a tie
    unknown = running_choice(
        "EL3102", terminal, [replace(slaves[0], active_group=None)]
    )
    assert (
        "run PDOs that none of the YAML's PDO groups describes" in unknown.decisions[0]
    )


@pytest.mark.parametrize("route", [False, True])
def test_the_configs_init_writes_load_and_keep_secrets_out(
    tmp_path: Path, route: bool
) -> None:
    settings = layout.Settings(
        prefix="BL01T-EA-ECAT-01",
        target="192.0.2.50:48898",
        route_user="Administrator" if route else None,
        password_env="TWINCAT_PASSWORD" if route else None,
    )
    (tmp_path / "ioc.yaml").write_text(layout.ioc_yaml(settings))
    (tmp_path / "instance.yaml").write_text(layout.instance_ioc_yaml(settings))
    values = yaml.safe_load(layout.values_yaml(settings))

    config = load_ioc_config(tmp_path / "ioc.yaml")
    instance = load_ioc_config(tmp_path / "instance.yaml")

    assert (config.prefix, config.target) == ("BL01T-EA-ECAT-01", "192.0.2.50:48898")
    assert config.terminal_dirs == (tmp_path / "terminals",)
    assert config.chain == tmp_path / "chain.yaml"
    assert instance.screens_dir == Path("/epics/opi")
    if route:
        assert config.route is not None and instance.route is not None
        assert config.route.password_env == "TWINCAT_PASSWORD"
        assert instance.route.password_file == Path(
            "/run/secrets/twincat-route/password"
        )
        assert values["ioc-instance"]["volumes"][0]["secret"]["secretName"] == (
            "bl01t-ea-ecat-01-route"
        )
    else:
        assert config.route is None and "volumes" not in values["ioc-instance"]


def test_nothing_is_left_beside_dir_when_a_step_fails(tmp_path: Path) -> None:
    out = tmp_path / "rack"
    out.mkdir()
    (out / "mine.txt").write_text("mine")

    with pytest.raises(RuntimeError), layout.staging(out) as folder:
        (folder / "ioc.yaml").write_text("half")
        raise RuntimeError("a step failed")

    assert sorted(p.name for p in tmp_path.iterdir()) == ["rack"]
    assert [p.name for p in out.iterdir()] == ["mine.txt"]
    with layout.staging(out) as folder:
        (folder / "ioc.yaml").write_text("whole")
        assert layout.differences(out, folder) == ["added: ioc.yaml"]
        layout.commit(folder, out)
    assert sorted(p.name for p in out.iterdir()) == ["ioc.yaml", "mine.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rack"]


def test_a_check_of_a_dir_in_a_missing_folder_leaves_no_folder(tmp_path: Path) -> None:
    out = tmp_path / "new" / "rack"

    with layout.staging(out) as folder:
        (folder / "ioc.yaml").write_text("whole")
        assert layout.differences(out, folder) == ["added: ioc.yaml"]

    assert list(tmp_path.iterdir()) == []


PREFIX = "BL01T-EA-ECAT-01"
ESI_FILES = ("Beckhoff EL1xxx.xml", "Beckhoff EL31xx.xml")
"""The ESI of EL1014 and EL3102 only: an EL2024 has a YAML but no ESI."""


def init_from_chain(
    folder: Path, chain: str, out: Path, prefix: str = PREFIX
) -> tuple[Outcome, list[str]]:
    """`init --from-chain` in this process: its outcome and summary lines."""
    esi = folder / "esi"
    esi.mkdir(exist_ok=True)
    for name in ESI_FILES:
        (esi / name).write_bytes((ESI_SUBSET / name).read_bytes())
    path = folder / "rack-chain.yaml"
    path.write_text(chain, encoding="utf-8")
    settings = layout.Settings(prefix=prefix, target="192.0.2.50")
    request = InitRequest(settings, (esi,), out, from_chain=path)
    outcome = run_init(request, lambda line: None)
    return outcome, list(summary_lines(outcome, out, check=False))


def test_the_summary_lists_what_needs_a_human_decision(tmp_path: Path) -> None:
    out = tmp_path / "rack"
    (out / "terminals").mkdir(parents=True)  # a YAML of a type gone from the rack
    (out / "terminals" / "EL1084.yaml").write_bytes(
        (TERMINALS_DIR / "EL1084.yaml").read_bytes()
    )
    earlier = layout.Settings(prefix="BL01T-EA-OLD-01", target="192.0.2.50")
    (out / "ioc.yaml").write_text(layout.ioc_yaml(earlier), encoding="utf-8")
    chain = """\
masters:
- slaves:
  - {type: EK1100}
  - {type: EL1014, revision: 0x00190000}      # newer than the ESI's newest
  - {type: EL2024, revision: 0x00190000}      # no ESI of the type
  - {type: EL9410, product_code: 0x24c23052}  # nothing describes it
  - {type: EL3102, pdo_group: Standard}
  - {type: EL3102, pdo_group: Compact}
  - {type: EL3102, pdo_group: Compact}
"""

    outcome, lines = init_from_chain(tmp_path, chain, out)

    assert (
        "     1 x EL1014 revision 0x00190000: the YAML of the ESI's nearest "
        "revision (terminals/EL1014.yaml, revision 0x00130000)"
    ) in lines
    assert "     1 x EL9410 revision 0x00000000: no description (-)" in lines
    start = lines.index("needs a human decision: 5")
    decisions = lines[start + 1 : start + 6]
    assert decisions[0] == (
        "  EL3102 revision 0x00110000: terminals run different PDO groups "
        "('Compact' on 2, 'Standard' on 1); one YAML selects one ('Compact'): "
        "each is served with the group it runs, or give the others a YAML of "
        "their own"
    )
    assert decisions[1].startswith(
        "  EL2024 revision 0x00190000 (Term 3 (EL2024)): no ESI of the type; "
        "served from "
    )
    assert decisions[1].endswith(
        "EL2024.yaml, matched by name: give an ESI source that has it"
    )
    assert decisions[2] == (
        "  EL9410 revision 0x00000000 (Term 4 (EL9410)): unknown type (no ESI, "
        "no YAML, no process data): served with its identity and diagnostics only"
    )
    assert decisions[3] == (
        "  terminals/EL1084.yaml: no terminal on the rack uses EL1084 revision "
        "0x00120000 now; kept (delete it if it is gone for good)"
    )
    assert decisions[4] == (
        f"  {out / 'ioc.yaml'} keeps prefix 'BL01T-EA-OLD-01', not --prefix "
        f"'{PREFIX}': edit it if that changed"
    )
    assert lines[start + 6].startswith("the IOC will warn at start (")
    assert outcome.decisions == [line.removeprefix("  ") for line in decisions]
    assert (out / "terminals" / "EL1084.yaml").is_file()


def test_the_summary_names_the_longest_pv_against_the_budget(tmp_path: Path) -> None:
    out = tmp_path / "rack"
    chain = """\
masters:
- slaves:
  - {type: EK1100}
  - {type: EL1014}
  - {type: EL3102}
  - {type: EL2024}
"""

    outcome, lines = init_from_chain(
        tmp_path, chain, out, prefix="BL01T-EA-ECAT-LONG-01"
    )

    entries, _warnings = list_pvs(load_ioc_config(out / "ioc.yaml"))
    longest = max(len(entry.name) for entry in entries)
    named = outcome.served.longest
    assert len(named) == longest <= MAX_PV_LENGTH
    assert named in {entry.name for entry in entries}
    [line] = [line for line in lines if line.startswith("PVs: ")]
    assert line.startswith(
        f"PVs: {len(entries)}; longest PV name {longest} of 60 characters: {named}; "
    )


def test_init_selects_the_oversampling_factor_the_rack_runs(tmp_path: Path) -> None:
    out = tmp_path / "rack"
    chain = """\
masters:
- slaves:
  - {type: EK1100}
  - {type: EL3702, oversampling: 5}
  - {type: EL3702, oversampling: 5}
  - {type: EL3702, oversampling: 20}
  - {type: ELM3704-0000, pdo_group: Oversampling 20 (24Bit)}
"""
    shipped = load_terminals([TERMINALS_DIR])
    shipped_factor = shipped.get("EL3702").terminal.oversampling
    assert shipped_factor is not None and shipped_factor.selected_factor == 10
    assert shipped.get("ELM3704-0000").terminal.selected_pdo_group == (
        "Oversampling 1 (24Bit)"
    )

    outcome, _lines = init_from_chain(tmp_path, chain, out)

    found = [
        (slave.type_name, slave.oversampling, slave.pdo_group)
        for slave in rack_slaves(load_chain(out / "chain.yaml"))
    ]
    assert found[1:] == [
        ("EL3702", 5, None),
        ("EL3702", 5, None),
        ("EL3702", 20, None),
        ("ELM3704-0000", None, "Oversampling 20 (24Bit)"),
    ]
    written = load_terminals([out / "terminals"], use_cache=False)
    el3702 = written.get("EL3702").terminal.oversampling
    assert el3702 is not None and el3702.selected_factor == 5
    elm3704 = written.get("ELM3704-0000").terminal.active_group
    assert elm3704 is not None
    assert (elm3704.name, elm3704.oversampling_factor) == (
        "Oversampling 20 (24Bit)",
        20,
    )
    assert (
        "EL3702 revision 0x00020000: terminals (Term 2 (EL3702), Term 3 (EL3702), "
        "Term 4 (EL3702), ...) sample at different factors (5 on 2, 20 on 1); "
        "the YAML selects 5"
    ) in outcome.decisions


def test_a_group_the_engineer_chose_is_kept_on_the_next_run(tmp_path: Path) -> None:
    out = tmp_path / "rack"
    chain = """\
masters:
- slaves:
  - {type: EK1100}
  - {type: EL3102, pdo_group: Standard}
"""
    init_from_chain(tmp_path, chain, out)
    yaml_file = out / "terminals" / "EL3102.yaml"
    first = load_terminals([yaml_file], use_cache=False).get("EL3102").terminal
    assert first.selected_pdo_group == "Standard"  # what the rack runs
    select_group_command(yaml_file, "Compact")  # `terminals select-group`
    chosen = yaml_file.read_bytes()

    outcome, lines = init_from_chain(tmp_path, chain, out)

    assert yaml_file.read_bytes() == chosen
    assert outcome.changes == []  # the rack did not change: the file did
    decision = (
        "EL3102 revision 0x00110000: EL3102.yaml selects PDO group 'Compact', the "
        "rack runs 'Standard': kept (`terminals select-group` changes it)"
    )
    assert outcome.decisions == [decision]
    assert f"  {decision}" in lines
