"""Bounded, strict input: every file the CLI reads fails in one line, in
bounded time and memory, when it is too large, endless, an alias bomb, or
holds numbers no field can take (`fastcs_ethercat.bounded`)."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from fastcs_ethercat.bounded import (
    MAX_ESI_BYTES,
    MAX_TERMINAL_YAML_BYTES,
    MIB,
)
from fastcs_ethercat.chain.file import parse_chain
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi import build_catalog, parse_file
from fastcs_ethercat.esi.model import MAX_PDO_BITS, MAX_PDO_ENTRY_BITS
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.terminals.files import parse_terminal_text, read_terminal_file
from fastcs_ethercat.terminals.generate import terminal_from_esi
from tests.conftest import TERMINALS_DIR, loopback_env
from tests.processes import CLI
from tests.test_terminals_support import cache_home
from tests.test_terminals_support import run_cli as run_cli_here

BAD = Path(__file__).resolve().parent / "data" / "esi" / "bad"
_MEASURE = """
import json, resource, subprocess, sys
done = subprocess.run(sys.argv[1:], capture_output=True, text=True, timeout=120)
usage = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"rc": done.returncode, "stdout": done.stdout,
    "stderr": done.stderr, "cpu_s": usage.ru_utime + usage.ru_stime,
    "rss_mb": usage.ru_maxrss / 1024}))
"""
BOUND_S = 2.0
BOUND_MB = 200.0


@dataclass
class Measured:
    rc: int
    stdout: str
    stderr: str
    cpu_s: float
    """User + system time of the command (not wall-clock: the machine is shared)."""
    rss_mb: float


e2e = pytest.mark.e2e


def run_cli_measured(*args: str) -> Measured:
    """`fastcs-ethercat ARGS` in a child of a child, so its peak RSS and CPU
    time are its own (`RUSAGE_CHILDREN` of the middle process)."""
    command = [*CLI, *args]
    done = subprocess.run(
        [sys.executable, "-c", _MEASURE, *command],
        capture_output=True,
        text=True,
        timeout=180,
        env=loopback_env(),
        check=True,
    )
    measured = Measured(**json.loads(done.stdout))
    print(
        f"{args[:2]}: rc {measured.rc}, {measured.cpu_s:.2f} s CPU, "
        f"{measured.rss_mb:.0f} MB peak"
    )
    return measured


def assert_one_error_line(measured: Measured, *words: str) -> str:
    assert measured.rc == 2, measured.stderr
    assert "Traceback" not in measured.stderr
    errors = [
        line for line in measured.stderr.splitlines() if line.startswith("error:")
    ]
    assert len(errors) == 1, measured.stderr
    for word in words:
        assert word in errors[0]
    return errors[0]


def esi_with(tmp_path: Path, bit_len: str = "1", copies: int = 1) -> Path:
    """An ESI file of EL1084 #x00100000 (the intact device of the fixture),
    its first BitLen replaced; `copies`: the device again, each one changed."""
    lines = (BAD / "missing-elements.xml").read_text().splitlines(keepends=True)
    head, device, tail = lines[:9], "".join(lines[73:137]), lines[268:]
    device = device.replace("<BitLen>1</BitLen>", f"<BitLen>{bit_len}</BitLen>", 1)
    devices = [device]
    for copy in range(1, copies):
        devices.append(device.replace("<Name>", f"<Name>copy {copy} ", 1))
    path = tmp_path / "EL1084.xml"
    path.write_text("".join(head) + "".join(devices) + "".join(tail))
    return path


def test_the_base_esi_file_parses(tmp_path: Path) -> None:
    result = parse_file(esi_with(tmp_path))
    assert [d.type_name for d in result.devices] == ["EL1084"]
    assert result.warnings == ()


@e2e
def test_a_200_mb_esi_file_is_refused_fast_in_bounded_memory(tmp_path: Path) -> None:
    path = esi_with(tmp_path)
    with path.open("r+b") as stream:  # sparse: 200 MB on paper, cheap to make
        stream.truncate(200 * 1024 * 1024)

    measured = run_cli_measured("terminals", "list", "--esi", str(path))

    assert_one_error_line(measured, "no usable terminal type")
    assert f"{path}: ESI file: larger than 16 MiB" in measured.stderr
    assert measured.cpu_s < BOUND_S
    assert measured.rss_mb < BOUND_MB


@e2e
def test_an_esi_file_of_real_devices_over_the_cap_is_never_parsed(
    tmp_path: Path,
) -> None:
    """24 MiB of real device descriptions (EL1084 again and again; 6x
    Beckhoff's largest file): parsed, it would take about 12x its size in
    memory; it is refused on its size alone, so it costs what refusing a
    small file does."""
    one = esi_with(tmp_path).stat().st_size
    path = esi_with(tmp_path, copies=24 * MIB // one + 1)

    measured = run_cli_measured("terminals", "list", "--esi", str(path))

    assert_one_error_line(measured, "no usable terminal type")
    assert f"{path}: ESI file: larger than 16 MiB: refused" in measured.stderr
    assert measured.cpu_s < BOUND_S
    assert measured.rss_mb < BOUND_MB


def test_an_esi_member_of_a_zip_is_bounded(tmp_path: Path) -> None:
    import zipfile

    archive = tmp_path / "esi.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as out:
        out.writestr("big.xml", b" " * (MAX_ESI_BYTES + 1))
    catalog = build_catalog(archive, use_cache=False)
    assert len(catalog) == 0
    assert any("larger than 16 MiB" in warning for warning in catalog.warnings)


@e2e
@pytest.mark.parametrize(
    ("bit_len", "words"),
    [
        ("-8", "BitLen of PDO entry 'Input' -8 is out of range"),
        ("99999999999999999999", "BitLen '99999999999999999999' is not a number"),
        ("9" * 5000, "BitLen '99999999999999999999...' is not a number"),
        ("#x" + "f" * 17, "is not a number"),
    ],
)
def test_absurd_bit_lengths_are_one_line(
    tmp_path: Path, bit_len: str, words: str
) -> None:
    path = esi_with(tmp_path, bit_len)
    result = parse_file(path)
    assert result.devices == ()
    (warning,) = result.warnings
    text = str(warning)
    assert text.startswith(f"{path}:") and "device EL1084" in text, text
    assert words in text and "\n" not in text and len(text) < 300

    out = tmp_path / "out"
    listed = run_cli_measured("terminals", "list", "--esi", str(path))
    generated = run_cli_measured(
        "terminals", "generate", "EL1084", "--esi", str(path), "--out", str(out)
    )

    assert_one_error_line(listed, "no usable terminal type")
    assert_one_error_line(generated, "EL1084")
    assert not (out / "EL1084.yaml").exists()


def test_a_pdo_entry_longer_than_a_mapping_can_say_is_refused(tmp_path: Path) -> None:
    """A PDO mapping entry gives an entry's length in one byte: 256 bits is
    no entry (the ESI reader refuses it, so `generate` never writes it)."""
    path = esi_with(tmp_path, str(MAX_PDO_ENTRY_BITS + 1))
    (warning,) = parse_file(path).warnings
    assert "BitLen of PDO entry 'Input' 256 is out of range (0 to 255)" in str(warning)
    assert parse_file(esi_with(tmp_path, str(MAX_PDO_ENTRY_BITS))).warnings == ()


def test_an_esi_no_terminal_file_can_describe_is_one_line(tmp_path: Path) -> None:
    """A PDO named `Channel 300` (a sync manager takes at most 255 PDOs):
    what `generate` makes of it would fail the terminal file's ranges, so it
    says so in one line naming the file and device, not a traceback."""
    path = esi_with(tmp_path)
    path.write_text(path.read_text().replace("Channel 1<", "Channel 300<", 1))
    (device,) = parse_file(path).devices

    with pytest.raises(UserError) as error:
        terminal_from_esi(device)

    text = str(error.value)
    assert text.startswith(f"{path}: device EL1084: no terminal file can describe")
    assert "less than or equal to 255 (got 300)" in text and "\n" not in text


SHIPPED = TERMINALS_DIR / "EP4374-0002.yaml"


@pytest.mark.parametrize(
    ("before", "after", "words"),
    [
        # a PDO (symbol node): at most 255 entries of 255 bits
        (
            "    access: rw\n    type_name: INT\n    bit_size: 16\n",
            "    access: rw\n    type_name: INT\n    bit_size: 99999999999\n",
            f"symbol_nodes[2].bit_size: Input should be less than or equal to "
            f"{MAX_PDO_BITS} (got 99999999999)",
        ),
        # one PDO entry (member): its length is one byte of the mapping
        (
            "      bit_offset: 0\n      bit_size: 16\n      coe: ['0x7020:11'",
            "      bit_offset: 0\n      bit_size: 256\n      coe: ['0x7020:11'",
            "members[0].bit_size: Input should be less than or equal to 255",
        ),
        (
            "      bit_offset: 0\n      bit_size: 16\n      coe: ['0x7020:11'",
            "      bit_offset: 70000\n      bit_size: 16\n      coe: ['0x7020:11'",
            f"members[0].bit_offset: Input should be less than or equal to "
            f"{MAX_PDO_BITS}",
        ),
        ("    channels: [3, 4]", "    channels: [3, 256]", "channels[1]: Input"),
        # a CoE object: as far as the ESI reader goes
        (
            "    type_name: UDINT\n    bit_size: 32\n    access: ro\n"
            "    default_data: '89130000'",
            "    type_name: UDINT\n    bit_size: 99999999999\n    access: ro\n"
            "    default_data: '89130000'",
            "coe_objects[0].bit_size: Input should be less than or equal to 1048576",
        ),
    ],
)
def test_terminal_file_numbers_beyond_ethercat_are_one_line(
    tmp_path: Path, before: str, after: str, words: str
) -> None:
    """`terminals check` of a hand-edited file whose number EtherCAT cannot
    have: exit 2, one line naming the file, the line of the number, the
    field and the bound."""
    text = SHIPPED.read_text(encoding="utf-8")
    assert text.count(before) == 1, before
    path = tmp_path / SHIPPED.name
    path.write_text(text.replace(before, after), encoding="utf-8")
    changed = after.splitlines()
    row = next(i for i, line in enumerate(before.splitlines()) if line != changed[i])
    line = text[: text.index(before)].count("\n") + row + 1

    with cache_home(tmp_path / "cache"):
        checked = run_cli_here("terminals", "check", str(path))

    assert checked.code == 2, checked
    (error,) = checked.err.splitlines()
    assert error.startswith(f"error: {path}:{line}:"), (error, changed[row])
    assert words in error, error
    assert "terminal types OK" not in checked.out


def test_terminals_check_of_nothing_exits_2(tmp_path: Path) -> None:
    """A check that found no terminal type checked nothing: exit 2, one line
    (an empty directory; a YAML file without types)."""
    empty = tmp_path / "empty"
    empty.mkdir()
    (tmp_path / "none.yaml").write_text("{}\n", encoding="utf-8")

    with cache_home(tmp_path / "cache"):
        outcomes = [
            run_cli_here("terminals", "check", str(where))
            for where in (empty, tmp_path / "none.yaml")
        ]
        shipped = run_cli_here("terminals", "check", str(SHIPPED))

    for outcome in outcomes:
        assert outcome.code == 2, outcome
        assert outcome.out == "", outcome
        (error,) = outcome.err.splitlines()
        assert error.startswith("error: no terminal types found in "), error
    assert (shipped.code, shipped.out) == (0, "1 terminal types OK\n")


def test_a_terminal_yaml_file_has_a_size_cap(tmp_path: Path) -> None:
    """A terminal YAML file over 8 MiB is refused before it is read (a
    sparse file: large on paper, cheap to make); the IOC config's cap is
    `test_ioc_config`'s."""
    terminal = _sparse(tmp_path / "EL1084.yaml", MAX_TERMINAL_YAML_BYTES // MIB + 1)

    with pytest.raises(UserError) as too_big:
        read_terminal_file(terminal)
    with cache_home(tmp_path / "cache"):
        checked = run_cli_here("terminals", "check", str(terminal))

    assert str(too_big.value) == (
        f"{terminal}: terminal YAML file: larger than 8 MiB: refused"
    )
    assert checked.code == 2
    assert checked.err == f"error: {too_big.value}\n"


@e2e
def test_nothing_usable_exits_2(tmp_path: Path) -> None:
    path = tmp_path / "broken.xml"
    path.write_text("<EtherCATInfo><Vendor><Id>2</Id></Vendor>")

    measured = run_cli_measured("terminals", "list", "--esi", str(path))

    assert_one_error_line(measured, "no usable terminal type")
    assert "0 terminal types" not in measured.stdout


def test_a_second_different_copy_of_a_device_is_reported(tmp_path: Path) -> None:
    same = build_catalog(esi_with(tmp_path, copies=1), use_cache=False)
    assert same.warnings == ()
    path = esi_with(tmp_path, copies=2)
    catalog = build_catalog(path, use_cache=False)
    (warning,) = catalog.warnings
    assert "device EL1084 revision #x00100000: a second, different copy" in warning
    assert warning.startswith(f"{path}:")


def test_an_identical_copy_is_not_reported(tmp_path: Path) -> None:
    path = esi_with(tmp_path)
    text = path.read_text()
    start, end = text.index("<Device "), text.index("</Device>") + len("</Device>")
    path.write_text(text[:end] + "\n" + text[start:end] + text[end:])
    assert build_catalog(path, use_cache=False).warnings == ()


def _config(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "ioc.yaml"
    path.write_text(f"prefix: BL01\ntarget: 127.0.0.1\n{extra}")
    return path


@e2e
def test_an_endless_chain_is_refused_fast_in_bounded_memory(tmp_path: Path) -> None:
    config = _config(tmp_path, "chain: /dev/zero\n")

    measured = run_cli_measured("ioc", "--config", str(config), "--list-pvs")

    assert_one_error_line(measured, "/dev/zero: chain file: larger than 16 MiB")
    assert measured.cpu_s < BOUND_S
    assert measured.rss_mb < BOUND_MB


def alias_bomb(levels: int = 9, width: int = 9) -> str:
    """9 levels of 9: a billion nodes from under 300 bytes."""
    lines = ["a0: &a0 [" + ", ".join(["x"] * width) + "]"]
    for level in range(1, levels):
        refs = ", ".join([f"*a{level - 1}"] * width)
        lines.append(f"a{level}: &a{level} [{refs}]")
    return "\n".join(lines) + "\n"


@e2e
@pytest.mark.parametrize("where", ["config", "chain"])
def test_a_yaml_alias_bomb_is_refused_fast_in_bounded_memory(
    tmp_path: Path, where: str
) -> None:
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(alias_bomb())
    config = bomb if where == "config" else _config(tmp_path, f"chain: {bomb}\n")

    measured = run_cli_measured("ioc", "--config", str(config), "--list-pvs")

    assert_one_error_line(measured, f"{bomb}:", "aliases expand to more than")
    assert measured.cpu_s < BOUND_S
    assert measured.rss_mb < BOUND_MB


def test_a_few_aliases_are_fine() -> None:
    text = "a: &one {poll_rate_hz: 5}\nb: *one\n"
    assert parse_chain_or_error(f"masters: []\nx: {text}") is not None


def parse_chain_or_error(text: str) -> str:
    try:
        parse_chain(text, "c.yaml")
    except UserError as error:
        return str(error)
    return ""


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("masters: " + "9" * 5000, "c.yaml:1:10: not a usable value"),
        ("masters: " + "9" * 30, "c.yaml:1:10: number out of range"),
        ("masters: " + "[" * 80 + "]" * 80, "nested deeper than 64 levels"),
    ],
)
def test_yaml_numbers_and_depth_are_bounded(text: str, words: str) -> None:
    message = parse_chain_or_error(text)
    assert words in message and "\n" not in message


def test_a_huge_integer_in_a_terminal_file_is_one_line() -> None:
    with pytest.raises(UserError, match=r"^T.yaml:2:13: not a usable value"):
        parse_terminal_text("EL1084:\n  bit_size: " + "1" * 5000 + "\n", "T.yaml")


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        ("poll_rate_hz: true\n", "3:1: poll_rate_hz: a number is wanted, not true"),
        ("ads_timeout_ms: false\n", "ads_timeout_ms: a number is wanted, not false"),
        ("terminals:\n  T1: {poll_rate_hz: true}\n", "terminals.T1.poll_rate_hz"),
        ("ads_timeout_ms: " + "9" * 5000 + "\n", "3:17: not a usable value"),
    ],
)
def test_config_booleans_are_not_numbers(
    tmp_path: Path, extra: str, words: str
) -> None:
    path = _config(tmp_path, extra)
    with pytest.raises(UserError) as error:
        load_ioc_config(path)
    assert str(error.value).startswith(f"{path}:")
    assert words in str(error.value)


def test_a_prefix_must_not_end_in_a_colon(tmp_path: Path) -> None:
    path = tmp_path / "ioc.yaml"
    path.write_text("prefix: 'BL01:'\ntarget: 127.0.0.1\n")
    with pytest.raises(UserError, match="must not end in ':'"):
        load_ioc_config(path)


def test_a_chain_boolean_is_not_a_number() -> None:
    text = "system: {task_cycle_ms: true}\nmasters: []\n"
    assert "a number is wanted, not true" in parse_chain_or_error(text)


def test_an_acf_and_a_catio_file_are_bounded(tmp_path: Path) -> None:
    from fastcs_ethercat.ioc.access import check_acf
    from fastcs_ethercat.terminals.catio_import import read_catio_file

    with pytest.raises(UserError, match="access security file: larger than 1 MiB"):
        check_acf(_sparse(tmp_path / "big.acf", 2))
    with pytest.raises(UserError, match="catio file: larger than 64 MiB"):
        read_catio_file(_sparse(tmp_path / "catio.yaml", 65))


def _sparse(path: Path, megabytes: int) -> Path:
    with path.open("wb") as stream:
        stream.truncate(megabytes * 1024 * 1024)
    return path
