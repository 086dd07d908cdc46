"""Archiver Appliance and autosave lists, checked against the PV list: from a
tree built in process, and from `ioc --list-pvs --format ...` with the PLC
(the simulator) and without it (`--chain`)."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

import pytest

from fastcs_ethercat.chain.file import load_chain
from fastcs_ethercat.ioc.boot import chain_plan
from fastcs_ethercat.ioc.clients import ClientPool
from fastcs_ethercat.ioc.config import IocConfig
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.ioc.controllers.tree import PvEntry
from fastcs_ethercat.ioc.plan import SystemPlan
from fastcs_ethercat.ioc.pvlists import (
    OPERATOR_FIELDS,
    ArchiverPolicy,
    archiver_items,
    autosave_names,
    autosave_text,
    write_pv_lists,
)
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals.loader import load_terminals
from tests.conftest import REPO_ROOT
from tests.ioc_support import (
    ioc_env,
    list_pvs_text,
    new_token,
    terminals_with_coe,
    write_ioc_config,
)

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"
POLL_RATE_HZ = 10.0


@pytest.fixture(scope="module")
def terminals(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shipped YAML with EL3104's `AI Settings` CoE object selected."""
    return terminals_with_coe(tmp_path_factory.mktemp("pvlists") / "terminals")


@pytest.fixture(scope="module")
def entries(terminals: Path) -> list[PvEntry]:
    config = IocConfig(prefix="LISTS", target="127.0.0.1:1", terminal_dirs=(terminals,))
    registry = load_terminals([terminals])

    async def go() -> list[PvEntry]:
        plan = await chain_plan(load_chain(DEMO_CHAIN), registry, config, "test")
        pool = ClientPool("127.0.0.1", 1)
        root = RootController(config, lambda: _never(), registry)
        root.build(plan, Connection(pool, plan.net_id))
        await pool.close()
        return root.pvs()

    return asyncio.run(go())


async def _never() -> tuple[SystemPlan, Connection]:
    raise AssertionError("the plan is given")


EVERYTHING = ArchiverPolicy(raw=True, readbacks=True)


def _archived(item: dict[str, str]) -> str:
    return item["pv"].removeprefix("pva://")


def test_with_raw_and_readbacks_every_readable_pv_is_archived_once(
    entries: list[PvEntry],
) -> None:
    items = archiver_items(entries, POLL_RATE_HZ, EVERYTHING)

    assert [_archived(i) for i in items] == [e.name for e in entries if "r" in e.access]
    assert {e.source for e in entries if "r" not in e.access} == {"command"}


def test_by_default_no_raw_twin_and_no_readback(entries: list[PvEntry]) -> None:
    archived = {_archived(i) for i in archiver_items(entries, POLL_RATE_HZ)}
    readable = {e.name for e in entries if "r" in e.access}
    left_out = readable - archived
    scaled = {e.source for e in entries if e.datatype == "ExactFloat"}

    assert archived <= readable
    assert left_out and all(
        name.endswith("_RBV") or (name.endswith("Raw") and by.source in scaled)
        for name, by in ((e.name, e) for e in entries if e.name in left_out)
    )
    assert any(n.endswith("_RBV") for n in left_out)
    assert any(n.endswith("Raw") for n in left_out)
    assert {n.removesuffix("_RBV") for n in left_out if n.endswith("_RBV")} <= archived


def test_values_at_the_poll_period_states_on_change_texts_as_text(
    entries: list[PvEntry],
) -> None:
    by_name = {_archived(i): i for i in archiver_items(entries, POLL_RATE_HZ)}
    archived = [e for e in entries if e.name in by_name]
    symbols = [e for e in archived if e.source.startswith("Term ")]
    numbers = [e for e in symbols if e.datatype not in ("Bool", "Enum", "String")]
    states = [e for e in archived if e.datatype in ("Bool", "Enum")]
    texts = [e for e in archived if e.datatype == "String"]
    coe = [e for e in archived if e.source.startswith("CoE:")]

    assert numbers and states and texts and coe
    assert {(by_name[e.name]["samplingmethod"], by_name[e.name]["samplingperiod"])
            for e in numbers} == {("MONITOR", "0.1")}  # fmt: skip
    assert {(by_name[e.name]["samplingmethod"], by_name[e.name]["samplingperiod"])
            for e in states + coe} == {("MONITOR", "1")}  # fmt: skip
    assert all(by_name[e.name]["pv"] == f"pva://{e.name}" for e in texts)
    assert all(by_name[e.name]["pv"] == e.name for e in archived if e not in texts)


def test_slow_diagnostics_are_scanned(entries: list[PvEntry]) -> None:
    by_name = {_archived(i): i for i in archiver_items(entries, POLL_RATE_HZ)}
    diagnostics = [e for e in entries if e.source == "ioc" and e.datatype == "Int"]

    assert diagnostics
    assert {by_name[e.name]["samplingmethod"] for e in diagnostics} == {"SCAN"}


def test_include_and_exclude_patterns_choose_below_the_prefix(
    entries: list[PvEntry],
) -> None:
    policy = ArchiverPolicy(include=("ETH1:RIO1:MOD5:*",), exclude=("*:CH4:*",))
    archived = [
        _archived(i) for i in archiver_items(entries, POLL_RATE_HZ, policy, "LISTS")
    ]
    config = IocConfig.model_validate(
        {
            "prefix": "LISTS",
            "target": "127.0.0.1",
            "archiver": {"include": ["ETH1:RIO1:MOD5:*"], "exclude": ["*:CH4:*"]},
        }
    )

    assert archived and all(n.startswith("LISTS:ETH1:RIO1:MOD5:") for n in archived)
    assert "LISTS:ETH1:RIO1:MOD5:CH1:Value" in archived
    assert not [n for n in archived if ":CH4:" in n]
    assert config.archiver.policy() == policy


COMMAND_BITS = ("CtrlTara", "CtrlStartCalibration", "SetCounter")
"""Outputs that start something in the terminal when set: never restored."""


def _pv_and_field(line: str) -> tuple[str, str]:
    pv, field = line.rsplit(".", 1)
    return pv, field


def test_autosave_holds_the_operators_fields_and_never_a_value(
    entries: list[PvEntry],
) -> None:
    names = autosave_names(entries)
    fields: dict[str, set[str]] = {}
    for pv, field in map(_pv_and_field, names):
        fields.setdefault(pv, set()).add(field)
    by_name = {e.name: e for e in entries}
    outputs = [e.name for e in entries if e.access == "rw"]
    value = "LISTS:ETH1:RIO1:MOD5:CH1:Value"  # an EL3104 input
    text = autosave_text(entries, "LISTS")

    assert "VAL" not in set().union(*fields.values())
    assert set(fields) == {e.name for e in entries if e.source != "command"}
    assert all("DESC" in kept for kept in fields.values())
    assert {"HIHI", "LOLO", "HHSV", "LLSV", "HYST", "MDEL", "ADEL"} <= fields[value]
    assert any(by_name[pv].record == "mbbi" and "UNSV" in f for pv, f in fields.items())
    assert any(by_name[pv].record == "bi" and "OSV" in f for pv, f in fields.items())
    assert all(
        set(OPERATOR_FIELDS[by_name[pv].record]) == f for pv, f in fields.items()
    )
    for bit in COMMAND_BITS:
        bits = [n for n in outputs if n.endswith(f":{bit}")]
        assert bits and not set(bits) & set(names)
        assert all(fields[pv] == {"ZSV", "OSV", "COSV", "DESC"} for pv in bits)
    coe = [e.name for e in entries if e.source.startswith("CoE:") and e.access == "rw"]
    assert coe and not set(coe) & set(names)  # the terminal holds them
    assert text.splitlines()[2:] == names
    assert all(line.startswith("#") for line in text.splitlines()[:2])


def test_each_pv_names_the_record_fastcs_serves_it_as(
    entries: list[PvEntry],
) -> None:
    kinds = {(e.datatype, e.access, e.record) for e in entries}

    assert {
        ("Bool", "r", "bi"),
        ("Bool", "rw", "bo"),
        ("Int", "r", "longin"),
        ("Int", "rw", "longout"),
        ("ExactFloat", "r", "ai"),
        ("ExactFloat", "rw", "ao"),
        ("IntegralFloat", "rw", "ao"),
        ("Enum", "r", "mbbi"),
        ("Enum", "rw", "mbbo"),
        ("String", "r", "waveform"),
        ("Waveform", "r", "waveform"),
        ("Command", "w", ""),
    } <= kinds
    assert all(record in (*OPERATOR_FIELDS, "") for _, _, record in kinds)


def test_the_lists_are_written_into_a_folder(
    entries: list[PvEntry], tmp_path: Path
) -> None:
    archiver, autosave = write_pv_lists(
        tmp_path / "lists", entries, "LISTS", POLL_RATE_HZ
    )

    assert json.loads(archiver.read_text()) == archiver_items(
        entries, POLL_RATE_HZ, prefix="LISTS"
    )
    assert autosave.read_text() == autosave_text(entries, "LISTS")


def _check_against_the_pv_list(text: str, archiver: str, autosave: str) -> None:
    rows = [line.split(" ", 3) for line in text.splitlines()]
    entries = [PvEntry(*row) for row in rows]
    readable = [
        item["pv"] for item in archiver_items(entries, POLL_RATE_HZ, prefix="LISTS")
    ]
    records = {name for name, _, _, source in rows if source != "command"}
    kept = [line for line in autosave.splitlines() if not line.startswith("#")]
    any_field = set().union(*OPERATOR_FIELDS.values())
    assert [item["pv"] for item in json.loads(archiver)] == readable
    assert {pv for pv, field in map(_pv_and_field, kept) if field == "DESC"} == (
        records
    )
    assert {field for _, field in map(_pv_and_field, kept)} <= any_field


@pytest.mark.e2e
def test_the_lists_with_and_without_the_plc_match_the_pv_list(
    terminals: Path, tmp_path: Path
) -> None:
    env = {**ioc_env(new_token()), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    with SimProcess(DEMO_CHAIN, terminals=terminals, env=env) as sim:
        config = write_ioc_config(
            tmp_path, "LISTS", sim.pyads_ip, sim.net_id, terminal_dirs=[str(terminals)]
        )
        live = [
            list_pvs_text(config, env, "--format", fmt)
            for fmt in ("text", "archiver", "autosave")
        ]
    offline = [
        list_pvs_text(config, env, "--chain", str(DEMO_CHAIN), "--format", fmt)
        for fmt in ("text", "archiver", "autosave")
    ]

    _check_against_the_pv_list(*live)
    _check_against_the_pv_list(*offline)
    assert offline == live  # the same chain, with the PLC or without it
