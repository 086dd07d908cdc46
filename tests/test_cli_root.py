"""The CLI as a user meets it: version, help, log levels, one-line errors."""

from __future__ import annotations

import os

import pytest

from fastcs_ethercat import __version__
from tests.processes import run_cli_child, run_python_child

pytestmark = pytest.mark.e2e


def test_version_flag_prints_version() -> None:
    done = run_cli_child("--version")
    assert done.returncode == 0
    assert done.stdout.strip() == f"fastcs-ethercat {__version__}"


def test_unknown_command_exits_nonzero_without_traceback() -> None:
    done = run_cli_child("no-such-command")
    assert done.returncode != 0
    assert "Traceback" not in done.stderr


def _help(*command: str) -> str:
    done = run_cli_child(*command, "--help", env={**os.environ, "COLUMNS": "120"})
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.parametrize(
    "command",
    [(), ("ioc",), ("ioc", "schema"), ("demo",), ("sim",), ("bench",), ("terminals",)]
    + [("terminals", name) for name in ("list", "show", "generate", "check")],
    ids=lambda command: " ".join(command) or "root",
)
def test_help_shows_no_type_after_flags(command: tuple[str, ...]) -> None:
    text = _help(*command)

    assert "<bool>" not in text
    assert "--help" in text


@pytest.mark.parametrize("command", ["ioc", "demo", "sim", "bench"])
def test_every_command_takes_a_log_level(command: str) -> None:
    assert "--log-level [debug|info|warning|error|critical]" in _help(command)


@pytest.mark.parametrize("command", ["sim", "bench", "demo"])
def test_single_commands_do_not_promise_subcommands(command: str) -> None:
    assert "COMMAND [ARGS]" not in _help(command)


def test_bench_only_shows_its_sections_and_they_are_the_runners() -> None:
    from fastcs_ethercat.bench.runner import SECTIONS
    from fastcs_ethercat.cli.bench import SECTIONS as CHOICES

    assert CHOICES == SECTIONS
    assert "--only [" + "|".join(SECTIONS) + "]" in _help("bench")


def test_bench_and_terminals_share_one_esi_default() -> None:
    default = "default: the zip fetched by `terminals update-cache`"

    assert default in " ".join(_help("bench").split())
    assert "default: the zip fetched by `update-cache`" in " ".join(
        _help("terminals", "list").split()
    )


def test_a_bad_log_level_is_one_error_not_a_traceback() -> None:
    done = run_cli_child("--log-level", "loud", "ioc")

    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert "'loud' is not one of" in done.stderr


def test_ioc_without_a_config_says_what_to_give() -> None:
    done = run_cli_child("ioc")

    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "error: give the IOC configuration with --config FILE "
        "(`fastcs-ethercat ioc schema` prints its JSON schema)"
    ]


def test_root_help_lists_every_command_in_order_and_typos_get_a_suggestion() -> None:
    listed = [
        line.split()[0] for line in _help().split("Commands:")[1].splitlines()[1:]
    ]
    typo = run_cli_child("terminal")

    names = ["demo", "sim", "bench", "init", "terminals", "ioc", "chain"]
    assert listed == names
    assert typo.returncode == 2
    assert "Did you mean 'terminals'?" in typo.stderr


def test_the_ioc_command_imports_neither_esi_parser_nor_terminal_commands() -> None:
    """Groups of commands are imported when named: `ioc` pays for its own."""
    probe = """
import sys
from fastcs_ethercat.cli import app
sys.argv = ["fastcs-ethercat", "ioc"]  # no --config: a one-line error
try:
    app()
except SystemExit as exit:
    unused = ("fastcs_ethercat.cli.terminals", "fastcs_ethercat.esi",
              "fastcs_ethercat.terminals.generate", "rich",
              "fastcs_ethercat.commission", "fastcs_ethercat.cli.init")
    print(exit.code, *(name in sys.modules for name in unused))
"""
    done = run_python_child(probe)

    assert done.stdout.split() == ["2", *["False"] * 6], done.stderr
