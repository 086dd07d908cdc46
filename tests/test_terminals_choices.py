"""`terminals select` / `coe`: the choices the editor makes, from the command line."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer

from fastcs_ethercat.cli import _typer_app
from fastcs_ethercat.terminals.files import read_terminal_file, terminal_file_text
from fastcs_ethercat.terminals.selection import (
    SelectionError,
    parse_coe_target,
    rename_symbol,
    select_coe,
    select_symbols,
    set_oversampling,
    set_severity,
    set_units,
)

from .test_terminals_support import (
    ESI,
    TERMINALS,
    needs_esi,
    regenerated_old_el3104,
    run_cli,
)


@pytest.fixture
def el3104(tmp_path: Path) -> Path:
    path = tmp_path / "EL3104.yaml"
    shutil.copy(TERMINALS / "EL3104.yaml", path)
    return path


def test_select_and_deselect_symbols_by_template_or_fastcs_name(el3104: Path) -> None:
    off = run_cli("terminals", "select", str(el3104), "--off",
                  "ai_standard_channel_{channel}")  # fmt: skip
    assert off.code == 0, off.err
    assert off.out == "EL3104: 0 of 2 symbols selected\n"
    terminal = read_terminal_file(el3104)["EL3104"]
    assert [n.selected for n in terminal.symbol_nodes] == [False, False]
    on = run_cli("terminals", "select", str(el3104), "ai standard channel {channel}")
    assert on.code == 0, on.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_a_symbol_of_another_group_or_a_channel_name_is_refused(el3104: Path) -> None:
    other = run_cli("terminals", "select", str(el3104), "AI Compact Channel {channel}")
    assert other.code == 2 and other.err.count("\n") == 1
    assert "belongs to PDO group 'Compact', not to the selected 'Standard'" in (
        other.err
    )
    channel = run_cli("terminals", "select", str(el3104), "AI Standard Channel 2")
    assert channel.code == 2
    assert "is one channel of 'AI Standard Channel {channel}'" in channel.err
    unknown = run_cli("terminals", "select", str(el3104), "Nothing")
    assert unknown.code == 2 and "no symbol 'Nothing' (symbols: " in unknown.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_coe_objects_and_sub_indices(el3104: Path) -> None:
    whole = run_cli("terminals", "coe", str(el3104), "0x8000", "8010")
    assert whole.code == 0, whole.err
    terminal = read_terminal_file(el3104)["EL3104"]
    on = {o.index for o in terminal.coe_objects if o.selected}
    assert on == {0x8000, 0x8010}
    one = run_cli("terminals", "coe", str(el3104), "0x8020:0x11")
    assert one.code == 0, one.err
    obj = next(o for o in read_terminal_file(el3104)["EL3104"].coe_objects
               if o.index == 0x8020)  # fmt: skip
    assert obj.selected
    assert [s.subindex for s in obj.sub_items if s.selected] == [0x11]
    assert "      selected: false\n" in el3104.read_text(encoding="utf-8")
    off = run_cli("terminals", "coe", str(el3104), "--off", "0x8020:11", "0x8000",
                  "0x8010")  # fmt: skip
    assert off.code == 0, off.err
    assert not any(o.selected for o in read_terminal_file(el3104)["EL3104"].coe_objects)
    shipped = run_cli("terminals", "coe", str(el3104), "0x8000:06")  # its one
    assert shipped.code == 0, shipped.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()
    bad = run_cli("terminals", "coe", str(el3104), "0x8000:99")
    assert bad.code == 2 and "has no sub-index 99" in bad.err
    typo = run_cli("terminals", "coe", str(el3104), "0x80g0")
    assert typo.code == 2 and "'0x80g0' is not a CoE address" in typo.err


def test_choices_in_code_match_the_cli(el3104: Path) -> None:
    terminal = read_terminal_file(el3104)["EL3104"]
    changed = select_coe(select_symbols(terminal, ["AI Standard Channel {channel}"],
                                        on=False), ["0x8000"])  # fmt: skip
    assert run_cli("terminals", "select", str(el3104), "--off",
                   "AI Standard Channel {channel}").code == 0  # fmt: skip
    assert run_cli("terminals", "coe", str(el3104), "0x8000").code == 0
    assert el3104.read_text(encoding="utf-8") == terminal_file_text({"EL3104": changed})
    assert parse_coe_target("#x8000:1A") == (0x8000, 0x1A)


def test_names_and_factor_are_validated() -> None:
    el3104 = read_terminal_file(TERMINALS / "EL3104.yaml")["EL3104"]
    with pytest.raises(SelectionError, match="needs \\{channel\\}"):
        rename_symbol(el3104, 0, "value")
    with pytest.raises(SelectionError, match="is not a fastcs_name"):
        rename_symbol(el3104, 0, "Value {channel}")
    with pytest.raises(SelectionError, match="already the name of another symbol"):
        rename_symbol(el3104, 0, "ai_compact_channel_{channel}")
    assert rename_symbol(el3104, 0, "ai{channel}").symbol_nodes[0].fastcs_name == (
        "ai{channel}"
    )
    with pytest.raises(SelectionError, match="does not oversample"):
        set_oversampling(el3104, 2)
    el3702 = read_terminal_file(TERMINALS / "EL3702.yaml")["EL3702"]
    assert el3702.oversampling is not None
    changed = set_oversampling(el3702, 20).oversampling
    assert changed is not None and changed.selected_factor == 20
    with pytest.raises(SelectionError, match="7 is not an offered factor"):
        set_oversampling(el3702, 7)


@needs_esi
def test_a_sub_index_choice_survives_regenerate(tmp_path: Path) -> None:
    def select_one_sub_index(path: Path) -> None:
        assert run_cli("terminals", "coe", str(path), "0x8020:11").code == 0

    path, result = regenerated_old_el3104(
        tmp_path / "terminals", tmp_path / "cache", select_one_sub_index
    )
    assert result.code == 0, result.err
    terminal = read_terminal_file(path)["EL3104"]
    assert terminal.identity.revision_number == 0x00110000
    obj = next(o for o in terminal.coe_objects if o.index == 0x8020)
    assert obj.selected and [s.subindex for s in obj.sub_items if s.selected] == [0x11]


STANDARD = "AI Standard Channel {channel}"


def test_units_set_show_and_reset_from_the_cli(el3104: Path) -> None:
    shown = run_cli("terminals", "units", str(el3104), STANDARD)
    set_ = run_cli("terminals", "units", str(el3104), "ai_standard_channel_{channel}",
                   "--unit", "mV", "--scale", "0.30518")  # fmt: skip
    text = el3104.read_text(encoding="utf-8")
    precision = run_cli("terminals", "units", str(el3104), STANDARD,
                        "--member", "value", "--precision", "2")  # fmt: skip
    terminal = read_terminal_file(el3104)["EL3104"]
    value = terminal.symbol_nodes[0].members[-1]
    reset = run_cli("terminals", "units", str(el3104), STANDARD, "--reset")

    assert shown.code == 0, shown.err
    assert shown.out == (
        "EL3104: AI Standard Channel {channel}.Value: x 0.000305185 V, "
        "4 decimals (dscale +/-10)\n"
    )
    assert set_.code == 0, set_.err
    assert set_.out.endswith("x 0.30518 mV, 1 decimal (dscale +/-10; set here: "
                             "scale, unit)\n")  # fmt: skip
    assert "      dscale: +/-10\n      scale: 0.30518\n      unit: mV\n" in text
    assert precision.code == 0, precision.err
    assert (value.scale, value.unit, value.precision) == (0.30518, "mV", 2)
    assert reset.code == 0, reset.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_units_refused_in_one_line(el3104: Path) -> None:
    several = run_cli("terminals", "units", str(el3104), STANDARD,
                      "--member", "nope", "--unit", "V")  # fmt: skip
    zero = run_cli("terminals", "units", str(el3104), STANDARD, "--scale", "0")
    long = run_cli("terminals", "units", str(el3104), STANDARD, "--unit", "x" * 16)
    bits = run_cli("terminals", "units", str(el3104), "Nothing", "--unit", "V")

    assert several.code == 2 and several.err.count("\n") == 1
    assert "has no member 'nope' (members: 'Status.Underrange'" in several.err
    assert zero.code == 2 and "scale: Value error, a scale of 0" in zero.err
    assert long.code == 2 and "longer than a record's EGU" in long.err
    assert bits.code == 2 and "no symbol 'Nothing'" in bits.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_severity_set_and_back_to_the_names(el3104: Path) -> None:
    minor = run_cli("terminals", "severity", str(el3104), STANDARD, "minor",
                    "--member", "Status.Error")  # fmt: skip
    old_spelling = run_cli("terminals", "severity", str(el3104), STANDARD, "minor",
                           "--member", "Status__Error")  # fmt: skip
    text = el3104.read_text(encoding="utf-8")
    back = run_cli("terminals", "severity", str(el3104), STANDARD, "default",
                   "--member", "status_error")  # fmt: skip
    loud = run_cli("terminals", "severity", str(el3104), STANDARD, "loud",
                   "--member", "Status__Error")  # fmt: skip
    which = run_cli("terminals", "severity", str(el3104), STANDARD, "none")

    assert minor.code == 0, minor.err
    assert minor.out == (
        "EL3104: AI Standard Channel {channel}.Status.Error: minor (set)\n"
    )
    assert old_spelling.out == minor.out
    assert "Over- or Underrange\n      severity: minor\n" in text
    assert back.code == 0 and back.out.endswith("major (from its name)\n")
    assert loud.code == 2 and "choose none, minor, major or default" in loud.err
    assert which.code == 2 and "name one with --member" in which.err
    assert el3104.read_bytes() == (TERMINALS / "EL3104.yaml").read_bytes()


def test_units_and_severity_in_code_match_the_cli(el3104: Path) -> None:
    terminal = read_terminal_file(el3104)["EL3104"]
    changed = set_severity(
        set_units(terminal, STANDARD, "Value", unit="V", offset=-1.5),
        STANDARD,
        "Status__Overrange",
        "none",
    )
    with pytest.raises(SelectionError, match="'AI Standard Channel \\{channel\\}' "
                       "has 8 status bits; name one with --member"):  # fmt: skip
        set_severity(terminal, STANDARD, None, "none")
    assert run_cli("terminals", "units", str(el3104), STANDARD, "--unit", "V",
                   "--offset", "-1.5").code == 0  # fmt: skip
    assert run_cli("terminals", "severity", str(el3104), STANDARD, "none",
                   "--member", "Status__Overrange").code == 0  # fmt: skip
    assert el3104.read_text(encoding="utf-8") == terminal_file_text({"EL3104": changed})


@needs_esi
def test_units_and_severities_survive_regenerate(tmp_path: Path) -> None:
    def choose(path: Path) -> None:
        assert run_cli("terminals", "units", str(path), STANDARD, "--unit", "mV",
                       "--scale", "0.30518").code == 0  # fmt: skip
        assert run_cli("terminals", "severity", str(path), STANDARD, "minor",
                       "--member", "Status__Error").code == 0  # fmt: skip

    path, result = regenerated_old_el3104(
        tmp_path / "terminals", tmp_path / "cache", choose
    )
    assert result.code == 0, result.err
    terminal = read_terminal_file(path)["EL3104"]
    members = {m.name: m for m in terminal.symbol_nodes[0].members}
    assert terminal.identity.revision_number == 0x00110000
    assert (members["Value"].unit, members["Value"].scale) == ("mV", 0.30518)
    assert members["Status__Error"].severity == "minor"
    assert "symbol changed" not in result.out  # choices are not ESI facts


MEMBER_TYPED = {
    "fastcs-ethercat terminals units": (
        "ELM3704-0000",
        ["PAI Samples 2 Channel {channel}", "--unit", "mV", "--member"],
        "Samples.ARRAY [1]",
    ),
    "fastcs-ethercat terminals severity": (
        "EL3104",
        ["AI Standard Channel {channel}", "none", "--member"],
        "Status.Underrange",
    ),
}
"""Every command with an option that takes a member name: the file, the
arguments before the name, the name as `show` prints it."""


def commands_with(option: str) -> Iterator[str]:
    """Every command of the CLI (groups imported) that has `option`."""

    def walk(command: Any, context: Any) -> Iterator[str]:
        params = command.params
        if any(
            option in param.opts
            for param in params
            if param.param_type_name == "option"
        ):
            yield context.command_path
        for name in (
            command.list_commands(context) if hasattr(command, "list_commands") else ()
        ):
            child = command.get_command(context, name)
            yield from walk(child, child.context_class(child, context, name))

    root = typer.main.get_command(_typer_app)
    yield from walk(root, root.context_class(root, info_name="fastcs-ethercat"))


def test_show_prints_members_dotted() -> None:
    shown = run_cli("terminals", "show", "EL3104", "--esi", str(ESI))

    assert shown.code == 0, shown.err
    assert (
        "        members: Status.Underrange, Status.Overrange, Status.Limit 1, "
        "Status.Limit 2, Status.Error, Status.Sync error, Status.TxPDO State, "
        "Status.TxPDO Toggle, Value\n"
    ) in shown.out
    assert "__" not in shown.out


def test_every_member_option_takes_both_spellings(tmp_path: Path) -> None:
    """`Status.Underrange` as `show`, the editor and the docs write it, and
    `Status__Underrange` as the YAML keeps it: the same member, the same file."""
    assert sorted(commands_with("--member")) == sorted(MEMBER_TYPED)
    for command, (type_name, args, dotted) in MEMBER_TYPED.items():
        results = []
        for spelling in (dotted, dotted.replace(".", "__")):
            path = tmp_path / spelling.replace(" ", "_") / f"{type_name}.yaml"
            path.parent.mkdir()
            shutil.copy(TERMINALS / f"{type_name}.yaml", path)
            done = run_cli(*command.split()[1:], str(path), *args, spelling)
            assert done.code == 0, (command, spelling, done.err)
            results.append((done.out, path.read_bytes()))
        (out, text), again = results
        assert again == (out, text), command
        assert f".{dotted}: " in out  # said as `show` says it
        assert text != (TERMINALS / f"{type_name}.yaml").read_bytes()
