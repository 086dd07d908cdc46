"""`fastcs-ethercat init` as an engineer runs it, against the simulator of a
real rack: `ioc/rack-chain.yaml` (101 terminals), one EL1014 reporting an
older revision than the shipped YAML's and an EL3102 added (a type that
ships no YAML: the simulator plays it from the ESI's). Both need the ESI
(`tests/data/esi/beckhoff` holds every revision of them).

One simulator serves the tests that only read the rack; the online change
gets its own.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from fastcs_ethercat.chain.file import load_chain, parse_chain
from fastcs_ethercat.commission.rack import ChangeKind, rack_changes, rack_slaves
from fastcs_ethercat.esi.catalog import build_catalog
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals.files import write_terminal_file
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.loader import load_terminals
from tests.conftest import ESI_SUBSET, REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import (
    IOC_COMMAND,
    START_TIMEOUT,
    caget,
    free_port,
    ioc_env,
    list_pvs,
    start_ioc,
    wait_for,
)
from tests.processes import new_token, run_cli_child

pytestmark = pytest.mark.e2e

INIT_TIMEOUT_S = 600.0
RACK_CHAIN = REPO_ROOT / "ioc" / "rack-chain.yaml"
OLD_EL1014 = 0x00120000
ADDED = "Term 102 (EL3102)"
REMOVED = "Term 7 (EL2024)"
NET_ID = "127.0.0.1.1.1"


@dataclass(frozen=True)
class Rack:
    """The simulated rack and what plays it."""

    chain: Path
    terminals: Path
    token: str

    @property
    def prefix(self) -> str:
        return f"INIT{self.token[:6].upper()}"


@dataclass(frozen=True)
class Done:
    """One `init` run: its DIR and what it printed."""

    out: Path
    target: str
    result: subprocess.CompletedProcess[str]

    @property
    def stdout(self) -> str:
        return self.result.stdout


def run_init(rack: Rack, target: str, out: Path, *extra: str | Path) -> Done:
    done = run_cli_child("init", "--target", target, "--ams-net-id", NET_ID,
                         "--prefix", rack.prefix, "--esi", ESI_SUBSET, "--out", out,
                         *extra, env=ioc_env(rack.token),
                         timeout=INIT_TIMEOUT_S)  # fmt: skip
    return Done(out, target, done)


def files(folder: Path) -> dict[str, bytes]:
    return {
        path.relative_to(folder).as_posix(): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


@pytest.fixture(scope="module")
def rack(tmp_path_factory: pytest.TempPathFactory) -> Rack:
    """The chain and the simulator's terminal YAML (the shipped ones and an
    EL3102 from the ESI)."""
    folder = tmp_path_factory.mktemp("rack")
    terminals = folder / "terminals"
    shutil.copytree(TERMINALS_DIR, terminals)
    catalog = build_catalog(ESI_SUBSET)
    write_terminal_file(
        terminals / "EL3102.yaml", {"EL3102": terminal_from_esi(catalog.load("EL3102"))}
    )
    data = yaml.safe_load(RACK_CHAIN.read_text(encoding="utf-8"))
    slaves = data["masters"][0]["slaves"]
    first_el1014 = next(s for s in slaves if s["type"] == "EL1014")
    first_el1014["revision"] = OLD_EL1014
    slaves.append({"type": "EL3102"})
    chain = folder / "chain.yaml"
    chain.write_text(yaml.safe_dump(data), encoding="utf-8")
    return Rack(chain, terminals, new_token())


@pytest.fixture(scope="module")
def sim(rack: Rack) -> Any:
    with SimProcess(rack.chain, terminals=rack.terminals) as sim:
        yield sim


@pytest.fixture(scope="module")
def first(
    rack: Rack, sim: SimProcess, tmp_path_factory: pytest.TempPathFactory
) -> Done:
    out = tmp_path_factory.mktemp("first") / "bl01t-ecat"
    return run_init(rack, sim.pyads_ip, out)


def test_init_gives_every_type_and_revision_its_own_yaml(first: Done) -> None:
    assert first.result.returncode == 0, first.result.stderr[-3000:]
    out = first.stdout
    assert out.startswith("rack: 102 terminals on 1 master(s)\n")
    assert "   60 x EL2024 revision 0x00130000: shipped (terminals/EL2024.yaml)" in out
    assert "    1 x EL1014 revision 0x00120000: generated from the ESI " in out
    assert "   10 x EL1014 revision 0x00130000: shipped" in out
    assert "    1 x EL3102 revision 0x00110000: generated from the ESI " in out
    assert "needs a human decision: none" in out
    assert "longest PV name " in out and " of 60 characters: " in out
    progress = first.result.stderr
    assert "init: discovering " in progress
    assert "init: reading the ESI catalog of " in progress
    names = sorted(path.name for path in (first.out / "terminals").iterdir())
    assert names == [
        "EK1100.yaml", "EL1014.yaml", "EL1014_r00120000.yaml", "EL1084.yaml",
        "EL1502.yaml", "EL2024.yaml", "EL3102.yaml", "schema.json",
    ]  # fmt: skip
    registry = load_terminals([first.out / "terminals"])
    for slave in rack_slaves(load_chain(first.out / "chain.yaml")):
        product = registry.get(slave.type_name).terminal.identity.product_code
        assert slave.revision is not None
        match = registry.lookup(product, slave.revision)
        assert match is not None and match.exact, slave


def test_dir_holds_a_commented_config_and_a_services_instance(
    first: Done, rack: Rack
) -> None:
    out = first.out
    text = (out / "ioc.yaml").read_text(encoding="utf-8")
    assert text.startswith("# yaml-language-server: $schema=ioc.schema.json\n")
    assert (out / "ioc.schema.json").is_file()
    config = load_ioc_config(out / "ioc.yaml")
    assert config.terminal_dirs == (out / "terminals",)
    assert (config.prefix, config.target, config.chain) == (
        rack.prefix, first.target, out / "chain.yaml"
    )  # fmt: skip
    assert (out / "screens" / "index.bob").is_file()
    assert (out / "pvlists" / "archiver.json").is_file()
    instance = out / "instance" / rack.prefix.lower()
    assert "ioc-instance:" in (instance / "values.yaml").read_text(encoding="utf-8")
    served = load_ioc_config(instance / "config" / "ioc.yaml")
    assert served.screens_dir == Path("/epics/opi")
    assert files(instance / "config" / "terminals") == files(out / "terminals")
    assert (instance / "config" / "chain.yaml").read_bytes() == (
        out / "chain.yaml"
    ).read_bytes()


def test_the_ioc_of_dir_lists_every_terminal_from_its_own_yaml(
    first: Done, rack: Rack
) -> None:
    done = run_cli_child("ioc", "--config", first.out / "ioc.yaml", "--list-pvs",
                         env=ioc_env(rack.token), timeout=300)  # fmt: skip

    assert done.returncode == 0, done.stderr[-2000:]
    for sign in ("generic", "has no YAML", "served from", "no terminal YAML"):
        assert sign not in done.stderr
    names = [line.split(" ", 1)[0] for line in done.stdout.splitlines()]
    longest = max(names, key=len)
    assert len(longest) <= 60
    assert (
        f"PVs: {len(names)}; longest PV name {len(longest)} of 60 characters: "
        f"{longest}; "
    ) in first.stdout
    sources = done.stdout
    assert f"{ADDED}.AI Standard Channel 1.Value" in sources
    assert "Term 102 (EL1014)" not in sources


def test_an_ioc_from_dir_serves_changing_values(first: Done, rack: Rack) -> None:
    config = first.out / "ioc.yaml"
    env = ioc_env(rack.token)
    rows = list_pvs(config, env)
    name = next(
        row[0]
        for row in rows
        if row[3] == f"{ADDED}.AI Standard Channel 1.Value" and row[1] == "r"
    )
    ioc = start_ioc([*IOC_COMMAND, "--config", str(config)], rack.prefix, env,
                    rack.token)  # fmt: skip
    try:
        ioc.wait_for_line("ioc ready", START_TIMEOUT)
        seen: set[str] = set()

        def changed() -> bool:
            seen.add(caget(ioc, name).get(name, ""))
            time.sleep(0.3)
            return len(seen - {""}) >= 3

        assert wait_for(changed, timeout=30), seen
    finally:
        ioc.stop()


def test_the_chain_of_dir_plays_the_same_rack(
    first: Done, rack: Rack, tmp_path: Path
) -> None:
    out = first.out
    offline = run_init(rack, first.target, tmp_path / "offline", "--from-chain",
                       out / "chain.yaml")  # fmt: skip
    assert offline.result.returncode == 0, offline.result.stderr[-2000:]
    assert files(offline.out) == files(out)

    assert load_chain(out / "chain.yaml").terminal_dirs == ("terminals",)
    with SimProcess(out / "chain.yaml") as replay:  # plain `sim --chain FILE`
        again = run_init(rack, replay.pyads_ip, tmp_path / "replayed")
    assert again.result.returncode == 0, again.result.stderr[-2000:]
    replayed = {
        name: data.replace(replay.pyads_ip.encode(), first.target.encode())
        for name, data in files(again.out).items()
    }
    assert replayed == files(out)


def test_check_reports_an_online_change_and_init_updates_only_it(
    rack: Rack, tmp_path: Path
) -> None:
    out = tmp_path / "rack"
    with SimProcess(rack.chain, terminals=rack.terminals) as sim:
        target = sim.pyads_ip
        made = run_init(rack, target, out)
        assert made.result.returncode == 0, made.result.stderr[-2000:]
        el2024 = out / "terminals" / "EL2024.yaml"
        el2024.write_text("# outputs of the shutter crate\n" + el2024.read_text())
        el3102 = out / "terminals" / "EL3102.yaml"
        header, rest = el3102.read_text().split("\n", 1)
        el3102.write_text(f"{header}\n# the beam position monitor\n{rest}")
        config = out / "ioc.yaml"
        config.write_text(
            config.read_text().replace("poll_rate_hz: 10", "poll_rate_hz: 5")
        )
        edited = files(out)
        sim.add_fault("online_change", pdo_groups={ADDED: "Compact"}, removed=[REMOVED])

        check = run_init(rack, target, out, "--check")
        assert check.result.returncode == 1, check.result.stderr[-2000:]
        assert f"other PDO group: {ADDED}: 'Standard' -> 'Compact'" in check.stdout
        assert f"removed: {REMOVED} (EL2024 revision 0x00130000)" in check.stdout
        assert "changes on the rack since the last init: 2" in check.stdout
        assert files(out) == edited

        again = run_init(rack, target, out)
        assert again.result.returncode == 0, again.result.stderr[-2000:]
        final = run_init(rack, target, out, "--check")

    after = files(out)
    changed = {name for name in after if after[name] != edited.get(name)}
    assert {
        name for name in changed if not name.startswith(("screens/", "pvlists/"))
    } == {
        "chain.yaml",
        "terminals/EL3102.yaml",
        f"instance/{rack.prefix.lower()}/config/chain.yaml",
        f"instance/{rack.prefix.lower()}/config/terminals/EL3102.yaml",
        # the instance's copy of DIR's YAML takes the hand edit too
        f"instance/{rack.prefix.lower()}/config/terminals/EL2024.yaml",
    }
    assert after["terminals/EL2024.yaml"].startswith(
        b"# outputs of the shutter crate\n"
    )
    assert b"poll_rate_hz: 5" in after["ioc.yaml"]
    assert b"selected_pdo_group: Compact" in after["terminals/EL3102.yaml"]
    assert b"\n# the beam position monitor\n" in after["terminals/EL3102.yaml"]
    changes = rack_changes(
        rack_slaves(parse_chain(edited["chain.yaml"].decode())),
        rack_slaves(parse_chain(after["chain.yaml"].decode())),
    )
    assert [(change.kind, change.slave.name) for change in changes] == [
        (ChangeKind.PDO_GROUP, ADDED),
        (ChangeKind.REMOVED, REMOVED),
    ]
    assert final.result.returncode == 0, final.stdout


def test_a_target_that_does_not_answer_leaves_dir_untouched(
    rack: Rack, tmp_path: Path
) -> None:
    out = tmp_path / "rack"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    port = free_port(tcp=True, udp=False)

    done = run_init(rack, f"127.0.0.1:{port}", out)

    assert done.result.returncode == 2
    [line] = [x for x in done.result.stderr.splitlines() if not x.startswith("init:")]
    assert line.startswith("error: target: cannot discover the target: ")
    assert files(out) == {"notes.txt": b"mine\n"}
    assert sorted(path.name for path in tmp_path.iterdir()) == ["rack"]


def test_an_esi_source_that_lacks_a_type_is_refused(
    rack: Rack, sim: SimProcess, tmp_path: Path
) -> None:
    esi = tmp_path / "esi"
    esi.mkdir()
    shutil.copy(ESI_SUBSET / "Beckhoff EL1xxx.xml", esi)
    out = tmp_path / "rack"

    done = run_cli_child("init", "--target", sim.pyads_ip, "--ams-net-id", NET_ID,
                         "--prefix", rack.prefix, "--esi", esi, "--out", out,
                         timeout=INIT_TIMEOUT_S)  # fmt: skip

    assert done.returncode == 2
    [line] = [x for x in done.stderr.splitlines() if x.startswith("error")]
    assert line.startswith(
        "error: esi: no ESI description and no terminal YAML of EL3102 "
    )
    assert f"first {ADDED}" in line
    assert not out.exists()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["esi"]


def test_a_dir_that_is_a_file_is_refused(rack: Rack, tmp_path: Path) -> None:
    out = tmp_path / "rack"
    out.write_text("not a folder\n")

    done = run_cli_child("init", "--target", "127.0.0.1", "--prefix", rack.prefix,
                         "--esi", ESI_SUBSET, "--out", out,
                         timeout=INIT_TIMEOUT_S)  # fmt: skip

    assert done.returncode == 2
    assert done.stderr == (
        f"error: {out}: exists and is not a directory: give a directory with --out\n"
    )
    assert out.read_text() == "not a folder\n"
