"""The chain description: format, TwinCAT's defaults, one-line errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from fastcs_ethercat.chain.file import load_chain, parse_chain
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.twincat.target import SimTarget
from tests.conftest import DLS_TYPES
from tests.processes import run_cli_child
from tests.test_sim_model_support import (
    DEMO_CHAIN,
    REPO_ROOT,
    TERMINALS_DIR,
    demo_target,
    target_from_text,
)


def test_demo_chain_has_every_dls_terminal_type() -> None:
    chain = load_chain(DEMO_CHAIN)
    types = {slave.type for master in chain.masters for slave in master.slaves}
    assert set(DLS_TYPES) <= types
    assert len(chain.masters) == 1


def test_demo_chain_runs_non_default_pdo_groups() -> None:
    target = demo_target()
    slaves = {s.name: s for s in target.devices[0].master.slaves}
    el3104 = slaves["Term 5 (EL3104)"].terminal.active_group
    assert el3104 is not None and el3104.name == "Compact"
    el1502 = slaves["Term 8 (EL1502)"].terminal
    assert el1502.active_group is not None
    assert not el1502.active_group.is_default


def test_twincat_defaults_for_names_addresses_and_netids() -> None:
    target = target_from_text(
        """
system: {net_id: 10.1.2.3.1.1}
masters:
- slaves: [{type: EK1100}, {type: EL1014}]
- name: Second master
  slaves: [{type: EK1100}, {type: EL2024, name: Valves}]
"""
    )
    first, second = target.devices
    assert first.name == "Device 1 (EtherCAT)"
    assert str(first.master.net_id) == "10.1.2.3.2.1"
    assert str(second.master.net_id) == "10.1.2.3.3.1"
    assert [s.name for s in first.master.slaves] == [
        "Term 1 (EK1100)",
        "Term 2 (EL1014)",
    ]
    # Term numbers run on across masters, as in one TwinCAT project.
    assert [s.name for s in second.master.slaves] == ["Term 3 (EK1100)", "Valves"]
    assert [s.address for s in second.master.slaves] == [1001, 1002]
    assert target.net_ids == {
        target.system_net_id,
        first.master.net_id,
        second.master.net_id,
    }


def test_revision_and_serial_override_the_reported_identity() -> None:
    target = target_from_text(
        "masters:\n- slaves:\n  - {type: EL3104, revision: '#x00100000', serial: 42}\n"
    )
    identity = target.devices[0].master.slaves[0].identity
    assert identity.revision == 0x00100000
    assert identity.serial_number == 42
    assert identity.product_code == 0x0C203052


@pytest.mark.parametrize(
    ("text", "place", "words"),
    [
        ("masters: []\n", "1:", "at least 1"),
        ("masters:\n- slaves:\n  - typo: 1\n", "3:", "missing key 'type'"),
        ("masters:\n- slaves:\n  - type: EL1014\n    colour: red\n", "4:", "colour"),
        ("system: {net_id: 1.2.3}\nmasters: [{slaves: []}]\n", "1:", "NetId"),
        (
            "masters:\n- slaves:\n  - {type: EL1014, name: A}\n"
            "  - {type: EL1014, name: A}\n",
            "4:",
            "already used",
        ),
        (
            "masters:\n- slaves:\n  - {type: EL1014, signal: {kind: sin}}\n",
            "3:",
            "kind",
        ),
        ("masters:\n- slaves:\n  - {type: EL1014, name: A.B}\n", "3:", "no dots"),
        ("masters:\n- name: \u03a9\n  slaves: []\n", "2:", "Windows-1252"),
    ],
)
def test_format_errors_name_file_and_line(text: str, place: str, words: str) -> None:
    with pytest.raises(UserError) as caught:
        parse_chain(text, "bad-chain.yaml")
    message = str(caught.value)
    assert message.startswith(f"bad-chain.yaml:{place}")
    assert words in message
    assert "\n" not in message


@pytest.mark.parametrize(
    ("slave", "words"),
    [
        ("{type: EL9999}", "unknown terminal type 'EL9999'"),
        ("{type: EL3104, pdo_group: Fancy}", "no PDO group 'Fancy'"),
        ("{type: EL1014, pdo_group: Compact}", "static PDOs"),
        ("{type: EL3702, oversampling: 7}", "oversampling factors"),
        ("{type: EL1014, oversampling: 2}", "not an oversampling terminal"),
        ("{type: EL1014, signals: {Channel 9: {kind: constant}}}", "Channel 9"),
        ("{type: EL2024, signals: {Channel 1: {kind: constant}}}", "no input"),
    ],
)
def test_terminal_errors_name_the_slave(slave: str, words: str) -> None:
    text = f"masters:\n- slaves:\n  - {{type: EK1100}}\n  - {slave}\n"
    with pytest.raises(UserError) as caught:
        target_from_text(text)
    message = str(caught.value)
    assert message.startswith("test-chain.yaml:4:")
    assert "masters[0].slaves[1]" in message
    assert words in message


def test_missing_files_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such chain file"):
        load_chain(tmp_path / "absent.yaml")
    with pytest.raises(UserError, match="no such terminal directory"):
        SimTarget.from_chain(DEMO_CHAIN, tmp_path / "absent")


def test_from_chain_reads_a_chain_file_and_the_terminal_directory() -> None:
    target = SimTarget.from_chain(DEMO_CHAIN, TERMINALS_DIR, seed=3)
    assert target.describe()["slaves"] == len(load_chain(DEMO_CHAIN).masters[0].slaves)
    assert target.seed == 3


def test_example_chains_in_ioc_load() -> None:
    chains = sorted((REPO_ROOT / "ioc").glob("*-chain.yaml"))
    assert DEMO_CHAIN in chains
    for path in chains:
        target = SimTarget.from_chain(path, TERMINALS_DIR)
        assert target.describe()["symbols"] > 0, path


@pytest.mark.e2e
def test_the_cli_reports_a_bad_chain_in_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad-chain.yaml"
    bad.write_text("masters:\n- slaves:\n  - {type: EL9999}\n", encoding="utf-8")
    done = run_cli_child("sim", "--chain", bad, "--terminals", TERMINALS_DIR,
                         "--port", "0", "--udp-port", "0", timeout=60)  # fmt: skip
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"error: {bad}:3:")
    assert "EL9999" in lines[0]


def test_a_chain_plays_from_the_terminal_dirs_it_names(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`terminal_dirs`, relative to the chain file, replace the shipped types;
    each revision in them is played as its own (what `init` writes)."""
    from fastcs_ethercat.esi.catalog import build_catalog
    from fastcs_ethercat.terminals.files import write_terminal_file
    from fastcs_ethercat.terminals.generate import terminal_from_esi
    from tests.conftest import ESI_SUBSET

    rack = tmp_path / "rack"
    terminals = rack / "terminals"
    terminals.mkdir(parents=True)
    catalog = build_catalog(ESI_SUBSET)
    for name in ("EK1100.yaml", "EL1014.yaml"):
        (terminals / name).write_bytes((TERMINALS_DIR / name).read_bytes())
    write_terminal_file(
        terminals / "EL3102.yaml", {"EL3102": terminal_from_esi(catalog.load("EL3102"))}
    )
    older = terminal_from_esi(catalog.load("EL1014", 0x00120000))
    write_terminal_file(terminals / "EL1014_r00120000.yaml", {"EL1014": older})
    chain = rack / "chain.yaml"
    chain.write_text(
        "terminal_dirs: [terminals]\nmasters:\n- slaves:\n  - {type: EK1100}\n"
        "  - {type: EL3102}\n  - {type: EL1014, revision: 0x00120000}\n",
        encoding="utf-8",
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)

    target = SimTarget.from_chain(Path("..") / "rack" / "chain.yaml")

    slaves = target.devices[0].master.slaves
    assert [s.type_name for s in slaves] == ["EK1100", "EL3102", "EL1014"]
    assert slaves[2].terminal.identity.revision_number == 0x00120000
    assert target.notes == []  # the older EL1014 from its own revision's YAML
    with pytest.raises(UserError, match="unknown terminal type 'EL3102'"):
        SimTarget.from_chain(chain, TERMINALS_DIR)  # --terminals DIR wins


def test_terminal_dirs_that_are_not_there_name_the_chain_line(tmp_path: Path) -> None:
    chain = tmp_path / "chain.yaml"
    chain.write_text(
        "masters:\n- slaves: [{type: EK1100}]\nterminal_dirs: [absent]\n",
        encoding="utf-8",
    )

    with pytest.raises(UserError) as caught:
        SimTarget.from_chain(chain)

    message = str(caught.value)
    assert message.startswith(f"{chain}:3:1: terminal_dirs: ")
    assert f"{tmp_path / 'absent'}: no such terminal YAML" in message
    with pytest.raises(UserError, match=r"terminal_dirs: .*a list of folders"):
        parse_chain("terminal_dirs: []\nmasters:\n- slaves: [{type: EK1100}]\n")


def test_without_terminal_dirs_a_chain_plays_from_the_shipped_types(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # no terminals/ here: the shipped ones play it
    chain = load_chain(DEMO_CHAIN)
    assert chain.terminal_dirs is None

    target = SimTarget.from_chain(chain)

    assert target.describe()["slaves"] == len(chain.masters[0].slaves)
