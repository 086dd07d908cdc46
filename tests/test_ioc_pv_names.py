"""PV names of whole chains under a beamline prefix: short, stable, the same
suffixes for a terminal type wherever it sits (issue 14 item 1).

`ioc --list-pvs` runs as a user runs it against the simulator of the demo
and the rack chain (e2e); the position test builds the tree in-process.
"""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

import pytest

from fastcs_ethercat.bench.chains import terminals_with_coe
from fastcs_ethercat.ioc.naming import MAX_PV_LENGTH, RBV_SUFFIX
from fastcs_ethercat.sim.process import SimProcess
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.ioc_support import ioc_env
from tests.processes import new_token, run_cli_child
from tests.tree_support import BEAMLINE_PREFIX, built_tree, chain_text

SHORTENED = re.compile(r"PV name shortened: .*: (\S+) -> (\S+) \((.*)\)$")
TERMINAL = re.compile(r":(MOD\d+):")


def _suffixes_by_terminal(names: list[str]) -> dict[str, set[str]]:
    found: dict[str, set[str]] = defaultdict(set)
    for name in names:
        if match := TERMINAL.search(name):
            found[match.group(1)].add(name[match.end() :])
    return found


def test_el3104s_anywhere_on_the_bus_have_the_same_suffixes(tmp_path: Path) -> None:
    """MOD1 hangs off the master (no coupler), MOD104 sits behind the first
    coupler after 100 other terminals, MOD107 behind a coupler of its own;
    the EL1502s' longest names are shortened, the same way everywhere."""
    slaves = ["EL3104", "EL1502", "EK1100", *["EL2024"] * 100, "EL3104"]
    slaves += ["EK1100", "EL1502", "EL3104"]
    chain = tmp_path / "chain.yaml"
    chain.write_text(chain_text(slaves))

    root = built_tree(chain)

    by_terminal = _suffixes_by_terminal([entry.name for entry in root.pvs()])
    assert by_terminal["MOD1"] == by_terminal["MOD104"] == by_terminal["MOD107"]
    assert "CH4:Value" in by_terminal["MOD1"]
    assert by_terminal["MOD2"] == by_terminal["MOD106"]
    assert "EnableOutputFnctns_RBV" in by_terminal["MOD2"]  # at its limit
    assert not any(shortening.hashed for shortening in root.names.shortened)


@pytest.mark.e2e
@pytest.mark.parametrize("chain", ["demo-chain.yaml", "rack-chain.yaml"])
def test_list_pvs_under_a_beamline_prefix_needs_no_hash(chain: str) -> None:
    with SimProcess(REPO_ROOT / "ioc" / chain, terminals=TERMINALS_DIR) as sim:
        done = run_cli_child(
            "--log-level", "debug", "ioc", "--config", "ioc/demo.yaml",
            "--prefix", BEAMLINE_PREFIX, "--target", f"{sim.host}:{sim.tcp_port}",
            "--ams-net-id", sim.net_id, "--list-pvs",
            cwd=REPO_ROOT, env=ioc_env(new_token()),
        )  # fmt: skip

    assert done.returncode == 0, done.stderr[-2000:]
    names = [line.split()[0] for line in done.stdout.splitlines()]
    shortenings = [
        m.groups() for m in map(SHORTENED.search, done.stderr.splitlines()) if m
    ]
    segments = {segment for _, segment, _ in shortenings}
    shortened = [
        name
        for name in names
        if name.removesuffix(RBV_SUFFIX).rpartition(":")[2] in segments
        or any(f":{segment}:" in name for segment in segments)
    ]
    hashed = [s for s in shortenings if not s[2].startswith(("vowels", "words"))]
    share = len(shortened) / len(names)
    longest = max(map(len, names))
    print(f"{chain}: {len(names)} PVs, {len(shortened)} shortened ({share:.1%}),"
          f" {len(hashed)} hashed, the longest {longest} characters")  # fmt: skip
    assert all(len(name) <= MAX_PV_LENGTH for name in names)
    assert hashed == []
    assert share <= 0.02, shortened
    if chain == "demo-chain.yaml":  # Compact (Term 5) and Standard (Term 22)
        by_terminal = _suffixes_by_terminal(names)
        values = {f"CH{n}:Value" for n in range(1, 5)}
        assert values <= by_terminal["MOD5"] and values <= by_terminal["MOD22"]


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("key", "alias", "other"),
    [
        ("Term 1 (EK1100)^Term 5 (EL3104)", "MOD6", "Term 6 (EL2024)' (MOD6)"),
        (
            "Term 21 (EK1122)^Term 22 (EL3104)^AI Standard Channel 1.Value",
            "Error",
            "AI Standard Channel 1.Status.Error' (Error)",
        ),
        (
            "Term 1 (EK1100)^Term 5 (EL3104)^Coe ai_settings_8000_enable_filter",
            "Presentation",
            "Coe ai_settings_8000_presentation' (Presentation)",
        ),
    ],
)
def test_an_alias_equal_to_a_generated_name_stops_the_ioc_in_one_line(
    tmp_path: Path, key: str, alias: str, other: str
) -> None:
    """Issue 11 item 7: before, the other PV was renamed with a hash, exit 0."""
    config = tmp_path / "ioc.yaml"
    path = f"Device 1 (EtherCAT)^{key}"
    config.write_text(
        f"prefix: {BEAMLINE_PREFIX}\ntarget: 127.0.0.1\n"
        f"pv_aliases:\n  '{path}': {alias}\n"
        + ("terminal_dirs: [terminals]\n" if "Coe" in key else "")
    )
    if "Coe" in key:
        terminals_with_coe(TERMINALS_DIR, tmp_path / "terminals")
    with SimProcess(
        REPO_ROOT / "ioc" / "demo-chain.yaml", terminals=TERMINALS_DIR
    ) as sim:
        done = run_cli_child(
            "ioc", "--config", config, "--target", f"{sim.host}:{sim.tcp_port}",
            "--ams-net-id", sim.net_id, env=ioc_env(new_token()),
        )  # fmt: skip

    last = done.stderr.strip().splitlines()[-1]
    assert done.returncode == 2, done.stderr[-2000:]
    assert last.startswith(f"error: pv_aliases['{path}']: alias '{alias}' is also")
    assert other in last and "ready" not in done.stdout
