"""Read YAML keeping every key's line; write the canonical terminal YAML text.

Reading composes the node tree first so duplicate keys are caught (PyYAML
would silently keep the last) and so a validation error deep inside a file
can name its line. Writing is deterministic: the same models always give
the same bytes, which is what lets load-then-save reproduce a file exactly.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError
from pydantic_core import ErrorDetails
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from fastcs_ethercat.bounded import YamlBudget, number_problem
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.yaml_style import FlowDict, FlowList, HexInt

Loc = tuple[Any, ...]

SCHEMA_FILE_NAME = "schema.json"
SCHEMA_HEADER = f"# yaml-language-server: $schema={SCHEMA_FILE_NAME}\n"


@dataclass
class LocatedYaml:
    """Plain data from a YAML document and the line:column of every key path."""

    data: Any
    path: Path | str
    places: dict[Loc, tuple[int, int]] = field(default_factory=dict)

    def where(self, loc: Loc) -> str:
        """`line:column` of the deepest known part of `loc` (1-based)."""
        for length in range(len(loc), -1, -1):
            place = self.places.get(tuple(loc[:length]))
            if place is not None:
                return f"{place[0]}:{place[1]}"
        return "1:1"


def format_loc(loc: Loc) -> str:
    """`EL3104.symbol_nodes[0].selected` for ("EL3104", "symbol_nodes", 0, ...)."""
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


def validation_error(
    located: LocatedYaml, loc: Loc, error: ValidationError
) -> UserError:
    """The first pydantic problem of the model validated at `loc`, as one line
    at its place in the file (terminal files and chain files alike)."""
    details = error.errors()
    error_loc, message = _friendly(details[0])
    return located_error(located, (*loc, *error_loc), message, len(details))


def located_error(
    located: LocatedYaml, loc: Loc, message: str, count: int = 1
) -> UserError:
    """UserError at `loc`'s line, prefixed with the key path; `count`: the
    problems found in all (the others are counted, not listed)."""
    more = ""
    if count > 1:
        more = f" (and {count - 1} more problem{'s' if count > 2 else ''})"
    key_path = format_loc(loc)
    return UserError(
        f"{key_path}: {message}{more}" if key_path else f"{message}{more}",
        path=located.path,
        where=located.where(loc),
    )


def _friendly(detail: ErrorDetails) -> tuple[Loc, str]:
    """A pydantic problem in the words of the file: an unknown or missing
    key by name; a validator's own message as it is; else the value shown."""
    loc: Loc = tuple(detail["loc"])
    kind = detail["type"]
    if kind == "extra_forbidden":
        return loc, f"unknown key {loc[-1]!r}"
    if kind == "missing":
        return loc[:-1], f"missing key {loc[-1]!r}"
    message = detail["msg"].removeprefix("Value error, ")
    if kind == "value_error":
        return loc, message
    shown = repr(detail.get("input"))
    if len(shown) > 40:
        shown = shown[:37] + "..."
    return loc, f"{message} (got {shown})"


def parse_yaml(text: str, path: Path | str) -> LocatedYaml:
    """Parse one YAML document; UserError (with line) on syntax or duplicates."""
    try:
        root = yaml.compose(text, Loader=_ComposeLoader)
    except yaml.MarkedYAMLError as error:
        raise _syntax_error(error, path) from None
    except yaml.YAMLError as error:
        raise UserError(f"not valid YAML: {error}", path=path) from None
    located = LocatedYaml(data=None, path=path)
    if root is None:
        return located
    builder = _Builder(located)
    located.data = builder.build(root, ())
    return located


def _syntax_error(error: yaml.MarkedYAMLError, path: Path | str) -> UserError:
    mark = error.problem_mark or error.context_mark
    where = f"{mark.line + 1}:{mark.column + 1}" if mark is not None else None
    problem = error.problem or error.context or "not valid YAML"
    return UserError(f"YAML syntax error: {problem}", path=path, where=where)


class _Loader(yaml.SafeLoader):
    """Safe loading only; used to compose nodes and construct scalars."""


if hasattr(yaml, "CSafeLoader"):
    _ComposeLoader: type = yaml.CSafeLoader
else:  # pragma: no cover - libyaml missing
    _ComposeLoader = _Loader


class _Builder:
    """Turns composed nodes into dicts/lists/scalars, recording key places."""

    def __init__(self, located: LocatedYaml) -> None:
        self._located = located
        self._constructor = _Loader("")
        self._open: set[int] = set()
        self._budget = YamlBudget()

    def _place(self, node: Node) -> tuple[int, int]:
        return node.start_mark.line + 1, node.start_mark.column + 1

    def _fail(self, node: Node, message: str) -> UserError:
        line, column = self._place(node)
        return UserError(message, path=self._located.path, where=f"{line}:{column}")

    def build(self, node: Node, loc: Loc) -> Any:
        if id(node) in self._open:
            raise self._fail(node, "recursive alias")
        problem = self._budget.problem(node, len(loc))
        if problem is not None:
            raise self._fail(node, problem)
        self._open.add(id(node))
        try:
            if isinstance(node, MappingNode):
                return self._mapping(node, loc)
            if isinstance(node, SequenceNode):
                items = []
                for position, item in enumerate(node.value):
                    self._located.places[(*loc, position)] = self._place(item)
                    items.append(self.build(item, (*loc, position)))
                return items
            return self._scalar(node)
        finally:
            self._open.discard(id(node))

    def _mapping(self, node: MappingNode, loc: Loc) -> dict[Any, Any]:
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, ScalarNode):
                raise self._fail(key_node, "a key must be plain text")
            key = self._scalar(key_node)
            if key in result:
                shown = format_loc((*loc, key))
                raise self._fail(key_node, f"duplicate key {shown!r}")
            self._located.places[(*loc, key)] = self._place(key_node)
            result[key] = self.build(value_node, (*loc, key))
        return result

    def _scalar(self, node: Node) -> Any:
        try:
            value = self._constructor.construct_object(node, deep=True)
        except yaml.MarkedYAMLError as error:
            raise _syntax_error(error, self._located.path) from None
        except ValueError as error:  # int() of over 4 300 digits, a bad date
            reason = str(error).split(":")[0]
            raise self._fail(node, f"not a usable value ({reason})") from None
        problem = number_problem(value)
        if problem is not None:
            raise self._fail(node, problem)
        return value


_BaseDumper: type[yaml.SafeDumper] = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


class _Dumper(_BaseDumper):
    """Writes hex ints, one-line lists and literal text blocks."""


def _represent_hex(dumper: yaml.SafeDumper, value: HexInt) -> yaml.Node:
    return dumper.represent_scalar("tag:yaml.org,2002:int", value.yaml_text())


def _represent_flow_list(dumper: yaml.SafeDumper, value: FlowList) -> yaml.Node:
    return dumper.represent_sequence(
        "tag:yaml.org,2002:seq", value.items, flow_style=True
    )


def _represent_flow_dict(dumper: yaml.SafeDumper, value: FlowDict) -> yaml.Node:
    return dumper.represent_mapping(
        "tag:yaml.org,2002:map", value.items, flow_style=True
    )


_YAML12_NUMBER = re.compile(
    r"^[-+]?(\.[0-9]+|[0-9][0-9_]*(\.[0-9_]*)?)([eE][-+]?[0-9]+)?$"
    r"|^0o[0-7]+$|^0x[0-9a-fA-F]+$|^[-+]?\.(inf|Inf|INF)$|^\.(nan|NaN|NAN)$"
)


def _represent_str(dumper: yaml.SafeDumper, value: str) -> yaml.Node:
    """Text blocks for multi-line text; quotes where YAML 1.2 sees a number.

    PyYAML quotes what YAML 1.1 would read as non-text; editors (YAML 1.2)
    would also read `1e05` (a hex default) as a float, so that is quoted too.
    """
    if "\n" in value:
        style: str | None = "|"
    elif _YAML12_NUMBER.match(value):
        style = "'"
    else:
        style = None
    return dumper.represent_scalar("tag:yaml.org,2002:str", value, style=style)


_Dumper.add_representer(HexInt, _represent_hex)
_Dumper.add_representer(FlowList, _represent_flow_list)
_Dumper.add_representer(FlowDict, _represent_flow_dict)
_Dumper.add_representer(str, _represent_str)


def dump_yaml(data: Any, header: str = SCHEMA_HEADER) -> str:
    """The canonical text for `data` (key order kept, no line folding)."""
    body = yaml.dump(
        data,
        Dumper=_Dumper,
        sort_keys=False,
        allow_unicode=True,
        default_flow_style=False,
        width=1_000_000,
        indent=2,
    )
    return header + body
