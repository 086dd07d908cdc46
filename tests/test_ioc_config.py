"""IOC instance configuration: YAML, flags on top, one-line errors."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.config import (
    MAX_CONFIG_BYTES,
    IocConfig,
    RouteConfig,
    load_ioc_config,
)
from fastcs_ethercat.shipped import BUILTIN_TERMINALS_DIR

FULL = """\
prefix: BL01T-EA-ECAT-01
target: 192.0.2.10:48898
ams_net_id: 192.0.2.10.1.1
local_net_id: 192.0.2.20.1.1
route:
  user: Administrator
  password_file: secrets/route.txt
poll_rate_hz: 20
terminals:
  "Term 5 (EL3104)": {poll_rate_hz: 2}
terminal_dirs: [terminals, /opt/site/terminals]
pv_aliases:
  "Device 1 (EtherCAT)^Term 1 (EK1100)^Term 5 (EL3104)": ShutterAdc
transports: {ca: true, pva: false}
screens_dir: screens
read_only: true
"""


def _write(tmp_path: Path, text: str, name: str = "ioc.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_full_file_loads_with_paths_relative_to_it(tmp_path: Path) -> None:
    config = load_ioc_config(_write(tmp_path, FULL))

    assert (config.target_host, config.target_port) == ("192.0.2.10", 48898)
    assert config.ams_net_id == "192.0.2.10.1.1"
    assert config.route is not None
    assert config.route.password_file == tmp_path / "secrets" / "route.txt"
    assert config.terminal_dirs == (tmp_path / "terminals", Path("/opt/site/terminals"))
    assert config.screens_dir == tmp_path / "screens"
    assert (config.transports.ca, config.transports.pva, config.read_only) == (
        True,
        False,
        True,
    )
    assert config.poll_period("Term 5 (EL3104)") == 0.5
    assert config.poll_period("Term 6 (EL2024)") == 0.05


def test_minimal_config_has_documented_defaults() -> None:
    config = load_ioc_config(None, {"prefix": "X", "target": "tc-host"})

    assert config == IocConfig(prefix="X", target="tc-host")
    assert config.target_port == 48898
    assert config.ams_net_id is None
    assert config.poll_period() == 0.1
    assert (config.transports.ca, config.transports.pva) == (True, True)
    assert config.terminal_dirs == (BUILTIN_TERMINALS_DIR,)
    assert (BUILTIN_TERMINALS_DIR / "EL3104.yaml").is_file()


def test_flags_override_the_file_and_unset_flags_do_not(tmp_path: Path) -> None:
    path = _write(tmp_path, FULL)

    config = load_ioc_config(
        path,
        {
            "prefix": "BL02T-EA-ECAT-01",
            "transports.pva": True,
            "target": None,
            "route.user": "Operator",
        },
    )

    assert config.prefix == "BL02T-EA-ECAT-01"
    assert config.transports.pva is True
    assert config.target == "192.0.2.10:48898"
    assert config.route is not None and config.route.user == "Operator"


@pytest.mark.parametrize(
    ("replace", "with_", "where", "message"),
    [
        ("read_only: true", "read_onyl: true", "read_onyl", "unknown key"),
        ("user: Administrator", "pasword: x", "route.pasword", "unknown key"),
        ("ams_net_id: 192.0.2.10.1.1", "ams_net_id: 1.2.3", "ams_net_id", "NetId"),
        ("target: 192.0.2.10:48898", "target: host:port", "target", "host:port"),
        ("poll_rate_hz: 20", "poll_rate_hz: 0", "poll_rate_hz", "greater than 0"),
        ("{poll_rate_hz: 2}", "{poll_rate_hz: -1}", "terminals.Term 5 (EL3104)", ""),
        (": ShutterAdc", ": shutter_adc", "pv_aliases", "PascalCase"),
        ("{ca: true, pva: false}", "{ca: false, pva: false}", "transports", "one of"),
        ("prefix: BL01T-EA-ECAT-01", "prefix: BL01T EA", "prefix", "only letters"),
        ("  user: Administrator", "  password_env: X", "route", "exactly one"),
    ],
)
def test_errors_name_file_and_key_in_one_line(
    tmp_path: Path, replace: str, with_: str, where: str, message: str
) -> None:
    assert replace in FULL
    path = _write(tmp_path, FULL.replace(replace, with_))

    with pytest.raises(UserError) as error:
        load_ioc_config(path)

    text = str(error.value)
    assert re.match(rf"{re.escape(str(path))}:\d+:\d+: {re.escape(where)}", text)
    assert message in text
    assert "\n" not in text


def test_flag_errors_say_they_came_from_the_command_line() -> None:
    with pytest.raises(UserError, match=r"^target \(command line\): "):
        load_ioc_config(None, {"prefix": "X", "target": "h:99999"})


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("prefix: [unclosed\n", "2:1"),
        ("- a list\n", None),
        ("prefix: X\n", "target"),
    ],
)
def test_bad_files_are_one_line_errors(
    tmp_path: Path, text: str, where: str | None
) -> None:
    path = _write(tmp_path, text)

    with pytest.raises(UserError) as error:
        load_ioc_config(path)

    assert str(error.value).startswith(f"{path}:{where}" if where else f"{path}:")
    assert "\n" not in str(error.value)


def test_missing_file_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such file"):
        load_ioc_config(tmp_path / "nope.yaml")


def test_route_password_from_file_or_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    secret = tmp_path / "route.txt"
    secret.write_text("p@ss word\nignored second line\n")
    monkeypatch.setenv("ROUTE_PW_FOR_TEST", "from-env")

    from_file = RouteConfig(password_file=secret)
    from_env = RouteConfig(password_env="ROUTE_PW_FOR_TEST")

    assert from_file.password().get_secret_value() == "p@ss word"
    assert from_env.password().get_secret_value() == "from-env"
    assert "p@ss" not in repr(from_file.password())
    with pytest.raises(UserError, match="NOT_SET_FOR_TEST is not set"):
        RouteConfig(password_env="NOT_SET_FOR_TEST").password()
    with pytest.raises(UserError, match="no such password file"):
        RouteConfig(password_file=tmp_path / "missing").password()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"prefix: X\xff\xfe\n", "not UTF-8 text (byte 0xff at offset 9)"),
        # the YAML library's own limit or ours, whichever the version meets first
        (b"prefix: " + b"[" * 5000 + b"]" * 5000 + b"\n", "nest"),
        (b"prefix: X\nprefix: Y\n", "duplicate key 'prefix'"),
        (b"x" * (MAX_CONFIG_BYTES + 1), "larger than 4 MiB"),
    ],
)
def test_hostile_files_are_one_line_errors(
    tmp_path: Path, content: bytes, message: str
) -> None:
    path = tmp_path / "ioc.yaml"
    path.write_bytes(content)

    with pytest.raises(UserError) as error:
        load_ioc_config(path)

    assert str(error.value).startswith(f"{path}:")
    assert message in str(error.value)
    assert "\n" not in str(error.value)


def test_an_endless_device_is_read_bounded() -> None:
    with pytest.raises(UserError, match=r"^/dev/zero: larger than"):
        load_ioc_config(Path("/dev/zero"))


def test_paths_resolve_against_the_file_wherever_it_is_loaded_from(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "config"
    folder.mkdir()
    path = _write(folder, FULL)
    monkeypatch.chdir(tmp_path)

    config = load_ioc_config(Path("config") / "ioc.yaml")

    assert config.screens_dir == Path("config") / "screens"
    assert config.terminal_dirs[0] == Path("config") / "terminals"
    assert (tmp_path / config.terminal_dirs[0]).parent == path.parent


def test_a_config_without_terminal_dirs_serves_those_its_chain_names(
    tmp_path: Path,
) -> None:
    rack = tmp_path / "rack"
    rack.mkdir()
    (rack / "chain.yaml").write_text(
        "terminal_dirs: [terminals, ../site]\nmasters:\n- slaves: [{type: EK1100}]\n",
        encoding="utf-8",
    )
    plain = _write(tmp_path, "prefix: X\ntarget: h\nchain: rack/chain.yaml\n")
    own = _write(
        tmp_path,
        "prefix: X\ntarget: h\nchain: rack/chain.yaml\nterminal_dirs: [mine]\n",
        name="own.yaml",
    )

    assert load_ioc_config(plain).terminal_dirs == (
        rack / "terminals",
        rack / ".." / "site",
    )
    assert load_ioc_config(own).terminal_dirs == (tmp_path / "mine",)
    flagged = load_ioc_config(None, {"prefix": "X", "target": "h",
                                     "chain": str(rack / "chain.yaml")})  # fmt: skip
    assert flagged.terminal_dirs[0] == rack / "terminals"
    (rack / "chain.yaml").write_text("masters:\n- slaves: [{type: EK1100}]\n")
    assert load_ioc_config(plain).terminal_dirs == (BUILTIN_TERMINALS_DIR,)
