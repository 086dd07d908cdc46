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

from fastcs_ethercat.bounded import MAX_ESI_BYTES
from fastcs_ethercat.chain.file import parse_chain
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi import build_catalog, parse_file
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.terminals.files import parse_terminal_text
from tests.conftest import loopback_env
from tests.processes import CLI

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
    assert f"{path}: ESI file: larger than 64 MiB" in measured.stderr
    assert measured.cpu_s < BOUND_S
    assert measured.rss_mb < BOUND_MB


def test_an_esi_member_of_a_zip_is_bounded(tmp_path: Path) -> None:
    import zipfile

    archive = tmp_path / "esi.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as out:
        out.writestr("big.xml", b" " * (MAX_ESI_BYTES + 1))
    catalog = build_catalog(archive, use_cache=False)
    assert len(catalog) == 0
    assert any("larger than 64 MiB" in warning for warning in catalog.warnings)


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
