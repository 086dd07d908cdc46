"""Reference pages written from the code at every build, never by hand.

The CLI page walks the Typer app (every command, argument and option with
its help), the configuration page walks the IOC config model's JSON schema,
and one page per shipped terminal type lists the PVs its default selection
serves, named by the IOC's own planner. A command, option or config key
added to the code appears by itself; an option without help text is a
Sphinx warning, so the `-W` build fails on it.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer

GENERATED = "generated"
"""Folder of `docs/reference/` the pages are written into (not in git)."""


@dataclass(frozen=True)
class CommandDoc:
    """One command of the CLI as its help shows it."""

    path: str
    """`fastcs-ethercat terminals list`."""
    command: Any
    """A Click command (Typer vendors its own Click: used by duck typing)."""
    context: Any


def walk_commands() -> Iterator[CommandDoc]:
    """Every command of `fastcs-ethercat`, groups first, in help order."""
    from fastcs_ethercat.cli import _typer_app

    root = typer.main.get_command(_typer_app)
    yield from _walk(root, root.context_class(root, info_name="fastcs-ethercat"))


def _is_group(command: Any) -> bool:
    return hasattr(command, "list_commands")


def _is_option(param: Any) -> bool:
    return param.param_type_name == "option"


def _walk(command: Any, context: Any) -> Iterator[CommandDoc]:
    yield CommandDoc(context.command_path, command, context)
    if _is_group(command):
        for name in command.list_commands(context):
            child = command.get_command(context, name)
            if child is not None and not child.hidden:
                context_class = child.context_class
                yield from _walk(child, context_class(child, context, name))


def undocumented_options() -> list[str]:
    """`command --option` for every option or command that has no help."""
    missing: list[str] = []
    for doc in walk_commands():
        if not (doc.command.help or doc.command.short_help):
            missing.append(f"{doc.path} (the command)")
        for param in doc.command.params:
            if _is_option(param) and not param.hidden and not param.help:
                missing.append(f"{doc.path} {param.opts[0]}")
    return missing


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def cli_page() -> str:
    """The CLI reference: usage, help, arguments and options of each command."""
    lines = [
        "# Command line",
        "",
        "Written from the code at every build (`docs/_ext/reference_pages.py`"
        " walks the Typer app): what `--help` prints, command by command.",
        "",
    ]
    for doc in walk_commands():
        command, context = doc.command, doc.context
        depth = min(doc.path.count(" ") + 1, 3)
        lines += [f"{'#' * (depth + 1)} `{doc.path}`", ""]
        help_text = (command.help or command.short_help or "").strip()
        usage = " ".join(command.collect_usage_pieces(context))
        lines += ["```text", f"{doc.path} {usage}", "```"]
        lines += ["", help_text.replace("\b\n", ""), ""]
        if _is_group(command):
            children = command.list_commands(context)
            lines += ["Commands: " + ", ".join(f"`{c}`" for c in children) + ".", ""]
        rows = []
        for param in command.params:
            if _is_option(param) and param.hidden:
                continue
            record = param.get_help_record(context)
            if record is not None:
                rows.append(record)
            elif param.param_type_name == "argument":
                rows.append((param.human_readable_name, "argument"))
        if rows:
            lines += ["| option | what |", "|---|---|"]
            lines += [f"| `{_cell(name)}` | {_cell(what)} |" for name, what in rows]
            lines.append("")
    return "\n".join(lines) + "\n"


def _type_of(schema: dict[str, Any]) -> str:
    if "$ref" in schema:
        return schema["$ref"].rsplit("/", 1)[-1]
    if "anyOf" in schema:
        kinds = [_type_of(s) for s in schema["anyOf"]]
        return " or ".join(k for k in kinds if k != "null") + (
            ", or null" if "null" in kinds else ""
        )
    kind = schema.get("type", "any")
    if kind == "array":
        return f"list of {_type_of(schema.get('items', {}))}"
    if kind == "object" and "additionalProperties" in schema:
        values = schema["additionalProperties"]
        return f"mapping to {_type_of(values) if isinstance(values, dict) else 'any'}"
    if "enum" in schema:
        return " / ".join(f"`{v}`" for v in schema["enum"])
    return str(kind)


def _bounds(schema: dict[str, Any]) -> str:
    words = {
        "minimum": ">=",
        "exclusiveMinimum": ">",
        "maximum": "<=",
        "exclusiveMaximum": "<",
        "maxLength": "length <=",
        "minLength": "length >=",
    }
    found = [f"{w} {schema[k]}" for k, w in words.items() if k in schema]
    for option in schema.get("anyOf", []):
        found += [f"{w} {option[k]}" for k, w in words.items() if k in option]
    return ", ".join(found)


def _model_table(title: str, schema: dict[str, Any], level: str) -> list[str]:
    required = set(schema.get("required", []))
    lines = [f"{level} `{title}`", "", _cell(schema.get("description", "")), ""]
    lines += ["| key | type | default | meaning |", "|---|---|---|---|"]
    for key, field in schema.get("properties", {}).items():
        default = (
            "required"
            if key in required
            else f"`{json.dumps(field['default'])}`"
            if "default" in field
            else ""
        )
        bounds = _bounds(field)
        kind = _type_of(field) + (f" ({bounds})" if bounds else "")
        meaning = _cell(field.get("description", "")) or "(see its type)"
        lines.append(f"| `{key}` | {_cell(kind)} | {_cell(default)} | {meaning} |")
    return [*lines, ""]


def config_page() -> str:
    """The IOC configuration file's keys, from its pydantic model."""
    from fastcs_ethercat.ioc.config import IocConfig

    schema = IocConfig.model_json_schema()
    lines = [
        "# IOC configuration",
        "",
        "Written from the code at every build (`IocConfig`'s JSON schema, the "
        "one `fastcs-ethercat ioc schema` prints, kept as `ioc/ioc.schema.json`)."
        " An IOC instance is one YAML file of these keys; unknown keys are "
        "errors. `ioc/beamline-example.yaml` is the commented reference, "
        "`ioc/demo.yaml` the demo's. Command-line flags override the file. "
        "Relative paths in a file (`terminal_dirs`, `screens_dir`, "
        "`access_security_file`, `route.password_file`, ...) are relative to "
        "that file, wherever the IOC is started from. A first line "
        "`# yaml-language-server: $schema=ioc.schema.json` lets editors check "
        "a file as it is typed, and a services repository's CI can validate "
        "with the schema. A file that is not UTF-8, nested absurdly deep or "
        "larger than 4 MiB is refused in one line naming it.",
        "",
    ]
    lines += _model_table("IocConfig", schema, "##")
    for name, part in sorted(schema.get("$defs", {}).items()):
        if "properties" in part:
            lines += _model_table(name, part, "###")
    return "\n".join(lines) + "\n"


PREVIEW_PREFIX = "PREFIX:ETH1:RIO1:MOD5"


def terminal_page(type_name: str, terminal: Any) -> str:
    """One shipped terminal type: identity, PDO groups, the PVs it serves."""
    from fastcs_ethercat.editor.pv_preview import preview_pvs

    ident = terminal.identity
    lines = [
        f"# {type_name}",
        "",
        f"{terminal.description}",
        "",
        "| | |",
        "|---|---|",
        f"| product code | `0x{ident.product_code:08x}` |",
        f"| revision | `0x{ident.revision_number:08x}` |",
        f"| group type | {terminal.group_type or ''} |",
        f"| ESI file | {terminal.esi_file or ''} |",
        "",
    ]
    if terminal.pdo_groups:
        lines += [
            "## PDO groups",
            "",
            "| group | default | selected |",
            "|---|---|---|",
        ]
        for group in terminal.pdo_groups:
            chosen = "yes" if group.name == terminal.selected_pdo_group else ""
            lines.append(
                f"| {group.name} | {'yes' if group.is_default else ''} | {chosen} |"
            )
        lines.append("")
    previews = preview_pvs(terminal, type_name, PREVIEW_PREFIX)
    lines += [
        "## PVs of the shipped selection",
        "",
        f"Under the terminal prefix `{PREVIEW_PREFIX}`, named as the IOC names "
        "them (an output also has its readback `_RBV`). Every terminal also "
        "serves its diagnostics: `AlState`, `AlStateText`, `LinkOk`, "
        "`LinkState`, `CrcErrors`, `Type` (see [PV names](../../pv-names.md)).",
        "",
    ]
    if previews:
        lines += ["| PV | serves | access |", "|---|---|---|"]
        for item in previews:
            suffix = item.pv.removeprefix(PREVIEW_PREFIX + ":")
            access = "write, `_RBV` read" if item.writable else "read"
            source = item.source.split(").", 1)[-1]
            lines.append(f"| `{suffix}` | {_cell(source)} | {access} |")
    else:
        lines.append("No symbol or CoE object selected: diagnostics only.")
    unselected = [c for c in terminal.coe_objects if not c.selected]
    lines += [
        "",
        "## Selectable",
        "",
        f"{len(terminal.symbol_nodes)} symbols, {len(terminal.coe_objects)} CoE "
        f"objects ({len(unselected)} not selected); select more with "
        "`fastcs-ethercat terminals select` / `coe` or the editor.",
        "",
    ]
    return "\n".join(lines)


def terminals_index(names: list[str]) -> str:
    return "\n".join(
        [
            "# Shipped terminal types",
            "",
            "One page per terminal type of `terminals/`, written from its YAML "
            "at every build.",
            "",
            "```{toctree}",
            ":maxdepth: 1",
            "",
            *names,
            "```",
            "",
        ]
    )


def _write(path: Path, text: str) -> None:
    """Write only what changed, so Sphinx rebuilds only those pages."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def write_pages(reference_dir: Path) -> list[str]:
    """Write every generated page; returns the problems to warn about."""
    from fastcs_ethercat.shipped import BUILTIN_TERMINALS_DIR
    from fastcs_ethercat.terminals.loader import load_terminals

    out = reference_dir / GENERATED
    _write(out / "cli.md", cli_page())
    _write(out / "config.md", config_page())
    registry = load_terminals([BUILTIN_TERMINALS_DIR], use_cache=False)
    names = []
    for item in sorted(registry, key=lambda i: i.type_name):
        _write(
            out / "terminals" / f"{item.type_name}.md",
            terminal_page(item.type_name, item.terminal),
        )
        names.append(item.type_name)
    _write(out / "terminals" / "index.md", terminals_index(names))
    for stale in (out / "terminals").glob("*.md"):
        if stale.stem not in names and stale.stem != "index":
            stale.unlink()
    return [f"CLI option without help text: {m}" for m in undocumented_options()]


def _builder_inited(app: Any) -> None:
    from sphinx.util import logging

    logger = logging.getLogger(__name__)
    for problem in write_pages(Path(app.srcdir) / "reference"):
        logger.warning(problem)


def setup(app: Any) -> dict[str, Any]:
    app.connect("builder-inited", _builder_inited)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
