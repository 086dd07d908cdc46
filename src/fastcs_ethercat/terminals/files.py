"""One terminal YAML file <-> validated `TerminalType`s, with precise errors.

Our layout: the file's top-level keys are terminal types. catio-terminals'
single-file layout (`terminal_types:`) records no bit offsets, so it is
refused with one line pointing at `terminals import` (`catio_import`), which
rebuilds it from the ESI. Every problem a user can make in a file becomes one
`UserError` naming the file, the line and the key path.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from fastcs_ethercat.bounded import MAX_TERMINAL_YAML_BYTES, read_text_bounded
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.safe_names import is_type_name
from fastcs_ethercat.terminals.checks import check_terminal, terminal_problems
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.yaml_io import (
    Loc,
    LocatedYaml,
    dump_yaml,
    located_error,
    parse_yaml,
    validation_error,
)

CATIO_LAYOUT_KEY = "terminal_types"


def read_text(path: Path) -> str:
    """A terminal YAML file's text (bounded), or a one-line `UserError`."""
    return read_text_bounded(path, MAX_TERMINAL_YAML_BYTES, what="terminal YAML file")


def read_terminal_file(path: Path | str) -> dict[str, TerminalType]:
    """Every terminal type in one file, validated."""
    path = Path(path)
    return parse_terminal_text(read_text(path), path)


def parse_terminal_text(text: str, path: Path | str) -> dict[str, TerminalType]:
    """Terminal types from YAML text; `path` only names the source in errors."""
    located = parse_yaml(text, path)
    if not isinstance(located.data, dict):
        raise UserError(
            "expected a mapping of terminal type names to terminal descriptions",
            path=path,
            where=located.where(()),
        )
    if CATIO_LAYOUT_KEY in located.data:
        raise not_importable(located)
    return validate_terminals(located, located.data, ())


def not_importable(located: LocatedYaml) -> UserError:
    """The one line a catio file gets when loaded as terminal YAML (without
    ESI: `catio_import` converts it)."""
    return UserError(
        "a catio-terminals file (terminal_types:) has no bit offsets: convert it "
        "with `fastcs-ethercat terminals import FILE --esi SRC --out DIR`",
        path=located.path,
        where=located.where((CATIO_LAYOUT_KEY,)),
    )


def validate_terminals(
    located: LocatedYaml, mapping: Mapping[Any, Any], prefix: Loc
) -> dict[str, TerminalType]:
    """Validate `{type name: description}` found at `prefix` in `located`."""
    terminals: dict[str, TerminalType] = {}
    for name, body in mapping.items():
        loc: Loc = (*prefix, name)
        if not is_type_name(name):
            raise UserError(
                f"{name!r} is not a terminal type name (like EL3104 or EL3356-0010)",
                path=located.path,
                where=located.where(loc),
            )
        terminals[name] = validate_terminal(located, body, loc)
    return terminals


def validate_terminal(located: LocatedYaml, body: Any, loc: Loc) -> TerminalType:
    """One terminal description: field types first, then consistency rules."""
    try:
        terminal = TerminalType.model_validate(body)
    except ValidationError as error:
        raise validation_error(located, loc, error) from None
    problems = terminal_problems(terminal)
    if problems:
        first = problems[0]
        raise located_error(located, (*loc, *first.loc), first.message, len(problems))
    return terminal


def terminal_file_text(terminals: Mapping[str, TerminalType]) -> str:
    """The canonical YAML text for these terminal types (our layout)."""
    for name, terminal in terminals.items():
        check_terminal(name, terminal)
    data = {
        name: terminal.model_dump(mode="python", exclude_defaults=True)
        for name, terminal in terminals.items()
    }
    return dump_yaml(data)


def write_terminal_file(
    path: Path | str, terminals: Mapping[str, TerminalType]
) -> None:
    """Write terminal types to `path` in the canonical text."""
    Path(path).write_text(terminal_file_text(terminals), encoding="utf-8")


def terminal_file_name(type_name: str) -> str:
    """`EL3104` -> `EL3104.yaml`: one file per terminal type; a name that is
    not a type name (`../../x`, `/abs/x`) is refused before it is a path."""
    if not is_type_name(type_name):
        raise UserError(
            f"{type_name[:80]!r} is not a terminal type name (like EL3104): "
            "refused as a file name"
        )
    return f"{type_name}.yaml"
