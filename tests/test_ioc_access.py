"""EPICS access security: ACF checks, and an IOC whose ACF refuses some writes.

The IOC (tests/data/alarm_ioc.py) puts its output in ASG OUTPUTS, its CoE-like
parameter in ASG COE and leaves a setting in DEFAULT. The test ACF lets
nobody who exists write OUTPUTS/COE and everyone write DEFAULT, so a caput is
refused on exactly the two restricted records while reads keep working.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from p4p.client.thread import RemoteError

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.access import (
    COE_GROUP,
    OUTPUTS_GROUP,
    READ_ONLY_GROUP,
    check_acf,
    read_only_acf,
)
from tests.conftest import REPO_ROOT, TEST_DATA
from tests.ioc_support import (
    START_TIMEOUT,
    IocProcess,
    caget,
    ioc_env,
    new_token,
    start_ioc,
    wait_for,
)
from tests.processes import run_python_child

EXAMPLE_ACF = REPO_ROOT / "ioc" / "access-example.acf"

RESTRICTING_ACF = """\
UAG(nobody) { no_such_user_here }
ASG(DEFAULT) {
    RULE(1, READ)
    RULE(1, WRITE)
}
ASG(OUTPUTS) {
    RULE(1, READ)
    RULE(1, WRITE) { UAG(nobody) }
}
ASG(COE) {
    RULE(1, READ)
    RULE(1, WRITE) { UAG(nobody) }
}
"""


@pytest.mark.e2e
def test_the_example_acf_parses_and_defines_the_groups_the_ioc_assigns() -> None:
    check_acf(EXAMPLE_ACF)
    groups = re.findall(r"^ASG\((\w+)\)", EXAMPLE_ACF.read_text(), re.MULTILINE)

    assert set(groups) == {"DEFAULT", OUTPUTS_GROUP, COE_GROUP}
    assert "access_security_file" in EXAMPLE_ACF.read_text()  # the config key


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("ASG(DEFAULT) {\n  RULE(1, READ\n}\n", ":line 3: syntax error"),
        (
            "ASG(OUT) {\n  RULE(1, WRITE) { UAG(nobody) }\n}\n",
            ":line 2: No User Access Group named 'nobody' defined",
        ),
        (
            "ASG(DEFAULT) {\n  RULE(1, READ)\n  RULE(1, WRIT)\n}\n",
            ":line 3: Ignoring RULE that contains an unsupported keyword",
        ),
    ],
)
def test_a_broken_acf_is_one_line_naming_file_and_line(
    tmp_path: Path, text: str, expected: str
) -> None:
    acf = tmp_path / "site.acf"
    acf.write_text(text)

    with pytest.raises(UserError) as raised:
        check_acf(acf)

    assert str(raised.value).startswith(f"{acf}{expected}")
    assert "\n" not in str(raised.value)


@pytest.mark.e2e
def test_read_only_acf_adds_a_group_without_write_rules(tmp_path: Path) -> None:
    open_default = read_only_acf(None, tmp_path)
    check_acf(open_default)
    (tmp_path / "site").mkdir()
    site = read_only_acf(EXAMPLE_ACF, tmp_path / "site")
    check_acf(site)
    clash = tmp_path / "clash.acf"
    clash.write_text("ASG(DEFAULT) {\n  RULE(1, READ)\n}\nASG(READ_ONLY) {\n}\n")

    assert re.search(r"ASG\(READ_ONLY\) \{\s*RULE\(1, READ\)\s*\}", site.read_text())
    assert site.read_text().startswith(EXAMPLE_ACF.read_text())
    with pytest.raises(UserError, match="READ_ONLY is reserved"):
        read_only_acf(clash, tmp_path)


def test_a_missing_acf_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="access security file not found"):
        check_acf(tmp_path / "absent.acf")


@pytest.fixture(scope="module")
def ioc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IocProcess]:
    acf = tmp_path_factory.mktemp("acf") / "restricting.acf"
    acf.write_text(RESTRICTING_ACF)
    token = new_token()
    prefix = f"ACF{token[:6].upper()}"
    command = [sys.executable, str(TEST_DATA / "alarm_ioc.py"), "--prefix", prefix]
    process = start_ioc([*command, "--acf", str(acf)], prefix, ioc_env(token), token)
    try:
        process.wait_for_line("alarm ioc ready", START_TIMEOUT)
        first = process.pv("Output")
        assert wait_for(lambda: first in caget(process, first), START_TIMEOUT)
        yield process
    finally:
        process.stop()


@pytest.mark.e2e
def test_records_carry_the_assigned_groups(ioc: IocProcess) -> None:
    fields = caget(
        ioc,
        ioc.pv("Output.ASG"),
        ioc.pv("CoeGain.ASG"),
        ioc.pv("Setting.ASG"),
        ioc.pv("Output_RBV.ASG"),
    )

    assert fields[ioc.pv("Output.ASG")] == OUTPUTS_GROUP
    assert fields[ioc.pv("CoeGain.ASG")] == COE_GROUP
    assert fields.get(ioc.pv("Setting.ASG"), "") == ""
    assert fields.get(ioc.pv("Output_RBV.ASG"), "") == ""


@pytest.mark.e2e
def test_caput_to_restricted_records_is_refused_and_reads_still_work(
    ioc: IocProcess,
) -> None:
    output = ioc.tool("caput", ioc.pv("Output"), "9")
    parameter = ioc.tool("caput", ioc.pv("CoeGain"), "9")
    info = ioc.tool("cainfo", ioc.pv("Output"))
    values = caget(ioc, ioc.pv("Output"), ioc.pv("Output_RBV"), ioc.pv("CoeGain"))

    assert "Write access denied" in output
    assert "Write access denied" in parameter
    assert re.search(r"Access:\s+read, no write", info), info
    assert values == {
        ioc.pv("Output"): "5",
        ioc.pv("Output_RBV"): "5",
        ioc.pv("CoeGain"): "1.5",
    }


@pytest.mark.e2e
def test_caput_to_a_default_group_record_still_writes(ioc: IocProcess) -> None:
    answer = ioc.tool("caput", ioc.pv("Setting"), "11")
    readback = wait_for(
        lambda: caget(ioc, ioc.pv("Setting_RBV")).get(ioc.pv("Setting_RBV")) == "11"
    )

    assert "denied" not in answer
    assert readback


@pytest.mark.e2e
def test_pva_puts_obey_the_acf_as_ca_puts_do(ioc: IocProcess) -> None:
    """QSRV serves the same records and asks the same access security."""
    with ioc.p4p_context() as context:
        with pytest.raises(RemoteError):
            context.put(ioc.pv("Output"), 8, wait=True)
        with pytest.raises(RemoteError):
            context.put(ioc.pv("CoeGain"), 8, wait=True)
        context.put(ioc.pv("Setting"), 12, wait=True)
        setting = wait_for(
            lambda: int(context.get(ioc.pv("Setting_RBV"))) == 12  # pyright: ignore[reportArgumentType]
        )
        output = int(context.get(ioc.pv("Output_RBV")))  # pyright: ignore[reportArgumentType]

    assert setting
    assert output != 8


@pytest.mark.e2e
def test_check_acf_leaves_this_process_alone(tmp_path: Path) -> None:
    """The parse runs in a child: this process's EPICS state is untouched."""
    done = run_python_child(
        "from pathlib import Path; import ctypes, sys\n"
        "from epicscorelibs.ioc import Com\n"
        "from fastcs_ethercat.ioc.access import check_acf\n"
        "check_acf(Path(sys.argv[1]))\n"
        "print(bool(ctypes.c_int.in_dll(Com, 'asActive').value))\n",
        str(EXAMPLE_ACF),
        timeout=60,
    )

    assert done.stdout.strip() == "False", done.stderr


@pytest.mark.e2e
def test_read_only_ioc_shows_every_output_as_read_only() -> None:
    token = new_token()
    prefix = f"ROI{token[:6].upper()}"
    command = [sys.executable, str(TEST_DATA / "alarm_ioc.py"), "--prefix", prefix]
    ioc = start_ioc([*command, "--read-only"], prefix, ioc_env(token), token)
    try:
        ioc.wait_for_line("alarm ioc ready", START_TIMEOUT)
        outputs = [ioc.pv(name) for name in ("Output", "CoeGain", "Setting")]
        assert wait_for(lambda: outputs[0] in caget(ioc, outputs[0]), START_TIMEOUT)
        infos = [ioc.tool("cainfo", name) for name in outputs]
        groups = caget(ioc, *(f"{name}.ASG" for name in outputs))
        refused = ioc.tool("caput", ioc.pv("Setting"), "12")
        values = caget(ioc, ioc.pv("Setting"), ioc.pv("Temperature"))
        reading = ioc.tool("cainfo", ioc.pv("Temperature"))
    finally:
        ioc.stop()

    assert all(re.search(r"Access:\s+read, no write", info) for info in infos)
    assert set(groups.values()) == {READ_ONLY_GROUP}
    assert "Write access denied" in refused
    assert values == {ioc.pv("Setting"): "7", ioc.pv("Temperature"): "21.5"}
    assert re.search(r"Access:\s+read, write", reading), reading
