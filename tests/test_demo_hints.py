"""What the demo tells a first-time user, without starting it: ports moved
off a busy 5064, lines with every variable they need, a PV list that is
never fatal."""

from __future__ import annotations

import shlex
import socket
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from fastcs_ethercat.cli import demo_hints
from fastcs_ethercat.cli.demo_hints import DemoHints, write_pv_list
from fastcs_ethercat.cli.ports import CA_SERVER_PORT, DemoPorts, demo_ports

NAMES = ["D:ETH1:RIO1:MOD5:CH1:Value", "D:ETH1:RIO1:MOD5:AlStateText", "D:X"]


@pytest.fixture
def busy_ca_port() -> Iterator[None]:
    """5064 held on loopback, by us or by whoever already holds it."""
    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        holder.bind(("127.0.0.1", CA_SERVER_PORT))
        holder.listen()
    except OSError:
        pass  # another IOC on this host has it: just as good
    yield
    holder.close()


def test_a_busy_ca_port_moves_the_demo_to_free_ports(busy_ca_port: None) -> None:
    ports = demo_ports({})

    assert ports.moved
    assert CA_SERVER_PORT not in (ports.ca, ports.pva, ports.pva_broadcast)
    for port, kind in ((ports.ca, socket.SOCK_STREAM), (ports.pva, socket.SOCK_STREAM)):
        with socket.socket(socket.AF_INET, kind) as probe:
            probe.bind(("127.0.0.1", port))  # free: nobody else has it
    hints = DemoHints(ports, NAMES)
    assert f"serving CA on {ports.ca}" in hints.port_lines()[0]


def test_ports_the_user_set_are_kept() -> None:
    environ = {
        "EPICS_CA_SERVER_PORT": "6064",
        "EPICS_PVA_SERVER_PORT": "6075",
        "EPICS_PVA_BROADCAST_PORT": "6076",
    }

    assert demo_ports(environ) == DemoPorts(6064, 6075, 6076, moved=False)


def test_the_lines_carry_their_variables_and_the_venvs_tools() -> None:
    hints = DemoHints(DemoPorts(6064, 6075, 6076, moved=True), NAMES)

    lines = hints.try_lines()
    caget, pvget, text = (shlex.split(line.split(" ", 2)[2]) for line in lines[1:4])

    assert caget[:3] == [
        "EPICS_CA_AUTO_ADDR_LIST=NO",
        "EPICS_CA_ADDR_LIST=127.0.0.1",
        "EPICS_CA_SERVER_PORT=6064",
    ]
    assert Path(caget[3]).name == "caget" and caget[4] == NAMES[0]
    assert "EPICS_PVA_BROADCAST_PORT=6076" in pvget and pvget[-1] == NAMES[0]
    assert text[-2:] == ["-S", NAMES[1]]


def test_the_pv_list_goes_to_a_folder_of_this_users(tmp_path: Path) -> None:
    saved = tempfile.tempdir
    tempfile.tempdir = str(tmp_path)
    try:
        line = write_pv_list("D", ["D:A r Int x", "D:B r Int y"])
        again = write_pv_list("D", ["D:A r Int x"])
    finally:
        tempfile.tempdir = saved

    path = Path(line.rsplit(" in ", 1)[1])
    assert line.startswith("demo: 2 PVs listed in ")
    assert again.startswith("demo: 1 PVs listed in ")
    assert path.parent.parent == tmp_path
    assert path.parent.stat().st_mode & 0o777 == 0o700
    assert path.read_text() == "D:A r Int x\n"


def test_an_unwritable_temp_folder_is_not_fatal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    monkeypatch.setattr(demo_hints.tempfile, "tempdir", str(not_a_folder))

    line = write_pv_list("D", ["D:A r Int x"])

    assert line.startswith("demo: 1 PVs (could not write their list: ")
    assert "--list-pvs" in line


def test_in_the_image_the_lines_name_the_hosts_tools(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(demo_hints.IMAGE_VARIABLE, "1")
    hints = DemoHints(DemoPorts(5064, 5075, 5076, moved=False), NAMES)

    caget = shlex.split(hints.try_lines()[1].split(" ", 2)[2])

    assert caget[3:] == ["caget", NAMES[0]]
