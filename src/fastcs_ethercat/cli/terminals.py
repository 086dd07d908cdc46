"""`fastcs-ethercat terminals`: ESI XML to terminal YAML, and the choices in it.

Commands: list, show, generate, regenerate, select-group, select, coe,
units, severity, import, edit, check, schema, update-cache. The choices
(select-group, select, coe, units, severity) are the functions of
`terminals.selection` the editor calls too. Modules only some commands need
(the comment keeper, catio import, the editor) are imported inside them;
this module itself is imported only for a `terminals` command (see
`cli.COMMAND_GROUPS`). Results go to stdout;
progress bars go to stderr; user errors are raised as `UserError` (one
line, exit code 2, printed by the root app).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
)

from fastcs_ethercat.cli.options import AmsNetIdOption, TargetOption
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.esi.model import CatalogEntry, EsiDevice, parse_esi_int
from fastcs_ethercat.loopback import LOOPBACK
from fastcs_ethercat.safe_names import file_in
from fastcs_ethercat.terminals.esi_sources import (
    VENDOR_ZIP_URL,
    cached_zip,
    download_vendor_zip,
    open_catalog,
)
from fastcs_ethercat.terminals.files import (
    read_terminal_file,
    terminal_file_name,
    terminal_file_text,
)
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.loader import load_terminals, terminal_paths
from fastcs_ethercat.terminals.meaning import member_scaling, member_severity
from fastcs_ethercat.terminals.merge import ChangeReport, merge_terminal
from fastcs_ethercat.terminals.model import UNIT_CHOICES, SeverityName, TerminalType
from fastcs_ethercat.terminals.revisions import regenerate_revision
from fastcs_ethercat.terminals.schema import schema_text, write_schema
from fastcs_ethercat.terminals.selection import (
    SelectionError,
    find_member,
    find_symbol,
    group_name,
    select_coe,
    select_group,
    select_symbols,
    set_severity,
    set_units,
)

terminals_app = typer.Typer(
    help="Read Beckhoff ESI XML and generate or regenerate terminal YAML.",
    no_args_is_help=True,
    rich_markup_mode=None,
)

EsiOption = Annotated[
    list[Path] | None,
    typer.Option(
        "--esi",
        metavar="SRC",
        help="ESI directory, XML file or Beckhoff_EtherCAT_XML.zip (repeatable); "
        "default: the zip fetched by `update-cache`.",
    ),
]
RevisionOption = Annotated[
    str | None,
    typer.Option(
        "--revision",
        metavar="REV",
        help="Revision number (0x00110000); default: newest.",
    ),
]


def _stderr() -> Console:
    return Console(stderr=True)


@contextmanager
def _progress(description: str, total: int) -> Iterator[Progress]:
    """A bar on stderr (drawn only on a terminal, removed when done)."""
    console = _stderr()
    progress = Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    with progress:
        progress.add_task(description, total=total)
        yield progress


def _advance(progress: Progress, text: str) -> None:
    task = progress.task_ids[0]
    progress.update(task, advance=1, description=text)


def _revision(text: str | None) -> int | None:
    if text is None:
        return None
    try:
        return parse_esi_int(text)
    except ValueError:
        raise UserError(
            f"--revision {text!r} is not a number (e.g. 0x00110000)"
        ) from None


def _catalog(esi: Sequence[Path] | None) -> EsiCatalog:
    with _progress("reading ESI catalog", 1):
        catalog = open_catalog(esi)
    for warning in catalog.warnings:
        typer.echo(f"warning: {warning}", err=True)
    if catalog.passive:
        shown = ", ".join(catalog.passive[:5])
        more = ", ..." if len(catalog.passive) > 5 else ""
        typer.echo(
            f"note: {len(catalog.passive)} passive devices without a product code "
            f"left out ({shown}{more})",
            err=True,
        )
    return catalog


@terminals_app.command("list")
def list_types(
    esi: EsiOption = None,
    filter_glob: Annotated[
        str | None,
        typer.Option("--filter", help="Only types matching this glob (EL31*)."),
    ] = None,
    every_revision: Annotated[
        bool,
        typer.Option("--revisions", help="One line per revision, not per type."),
    ] = False,
) -> None:
    """One line per terminal type: newest usable revision, product code, group
    type; revisions that do not parse are named at the end of the line."""
    catalog = _catalog(esi)
    if not any(entry.parses for entry in catalog.entries):
        raise UserError(
            f"no usable terminal type in the ESI sources ({len(catalog)} devices "
            f"read, {len(catalog.warnings)} warnings above)"
        )
    shown = 0
    for name in catalog.type_names():
        if filter_glob and not fnmatch.fnmatchcase(name.upper(), filter_glob.upper()):
            continue
        if every_revision:
            for entry in catalog.revisions(name):
                typer.echo(_revision_line(catalog, entry))
        else:
            typer.echo(_type_line(catalog, name))
        shown += 1
    typer.echo(f"{shown} terminal types")


def _entry_line(entry: CatalogEntry) -> str:
    groups = "yes" if entry.has_pdo_groups else "no"
    return (
        f"{entry.type_name:<16} revision=0x{entry.revision:08x} "
        f"product_code=0x{entry.product_code:08x} "
        f"group_type={entry.group_type or '-'} pdo_groups={groups}"
    )


def _type_line(catalog: EsiCatalog, name: str) -> str:
    chosen = catalog.newest_usable(name)
    if chosen is None:
        newest = catalog.revisions(name)[-1]
        return f"{_entry_line(newest)} UNUSABLE: no revision parses ({newest.problem})"
    broken = [e for e in catalog.revisions(name) if not e.parses]
    if not broken:
        return _entry_line(chosen)
    listed = ",".join(f"0x{e.revision:08x}" for e in broken)
    return f"{_entry_line(chosen)} not-parsed={listed}"


def _revision_line(catalog: EsiCatalog, entry: CatalogEntry) -> str:
    line = _entry_line(entry)
    if not entry.parses:
        return f"{line} NOT PARSED: {entry.problem}"
    if entry not in catalog.usable(entry.type_name):
        return f"{line} hidden"
    return line


@terminals_app.command("show")
def show(
    type_name: Annotated[str, typer.Argument(metavar="TYPE", help="e.g. EL3104")],
    esi: EsiOption = None,
    revision: RevisionOption = None,
) -> None:
    """PDOs, PDO groups (default marked), symbols and a CoE summary of a type."""
    catalog = _catalog(esi)
    device = catalog.load(type_name, _revision(revision))
    terminal = terminal_from_esi(device)
    revisions = [
        f"0x{e.revision:08x}" + ("" if e.parses else " (does not parse)")
        for e in catalog.revisions(device.type_name)
    ]
    for line in _describe(device, terminal, revisions):
        typer.echo(line)


def _describe(
    device: EsiDevice, terminal: TerminalType, revisions: list[str]
) -> list[str]:
    lines = [
        f"{device.type_name} revision=0x{device.revision:08x} "
        f"product_code=0x{device.product_code:08x} vendor_id=0x{device.vendor_id:08x}",
        f"  {device.description} (group type {device.group_type or '-'})",
        f"  source: {device.source}:{device.source_line}",
        f"  revisions: {', '.join(revisions)}",
        f"PDOs ({len(device.pdos)}):",
    ]
    for pdo in device.pdos:
        direction = "input " if pdo.direction == "tx" else "output"
        bits = sum(e.bit_len for e in pdo.entries)
        sm = f"sm {pdo.sm}" if pdo.sm is not None else "no sm"
        lines.append(
            f"  0x{pdo.index:04x} {direction} {pdo.name} "
            f"({bits} bits, {len(pdo.entries)} entries, {sm})"
        )
    lines.append(f"PDO groups ({len(terminal.pdo_groups)}):")
    for group in terminal.pdo_groups:
        mark = "*" if group.is_default else " "
        default = " (default)" if group.is_default else ""
        pdos = " ".join(f"0x{i:04x}" for i in group.pdo_indices)
        lines.append(f"  {mark} {group.name}{default}: {pdos}")
    lines.append(f"Symbols ({len(terminal.symbol_nodes)}):")
    for node in terminal.symbol_nodes:
        mark = "[x]" if node.selected else "[ ]"
        channels = (
            f" channels {','.join(map(str, node.channels))}" if node.channels else ""
        )
        over = " oversampled" if node.oversampled else ""
        lines.append(
            f"  {mark} {node.name_template}{channels}: {node.type_name}, "
            f"{node.bit_size} bits, {len(node.members)} members, {node.direction}{over}"
        )
        if len(node.members) > 1:
            names = ", ".join(member.shown_name for member in node.members)
            lines.append(f"        members: {names}")
    if terminal.oversampling is not None:
        over = terminal.oversampling
        lines.append(
            f"Oversampling: factors {', '.join(map(str, over.factors))}; "
            f"default {over.default_factor}"
        )
    lines.append(f"CoE objects ({len(terminal.coe_objects)}):")
    for obj in terminal.coe_objects:
        subs = f", {len(obj.sub_items)} sub-items" if obj.sub_items else ""
        access = obj.access or "-"
        kind = f"{obj.type_name}, {access}{subs}"
        lines.append(f"  0x{obj.index:04x} {obj.name} ({kind})")
    return lines


@terminals_app.command("generate")
def generate(
    type_names: Annotated[
        list[str], typer.Argument(metavar="TYPE...", help="Terminal types to generate.")
    ],
    out: Annotated[Path, typer.Option("--out", help="Directory for the YAML files.")],
    esi: EsiOption = None,
    revision: RevisionOption = None,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite existing files (choices lost).")
    ] = False,
    skip_existing: Annotated[
        bool,
        typer.Option("--skip-existing", help="Leave existing files as they are."),
    ] = False,
) -> None:
    """Generate one YAML file per terminal type (default choices).

    A type that fails writes nothing; the others are still written, and a
    summary at the end names every failure (exit code 2)."""
    catalog = _catalog(esi)
    wanted = _revision(revision)
    out.mkdir(parents=True, exist_ok=True)
    failed: list[str] = []
    written = 0
    with _progress("generating", len(type_names)) as progress:
        for requested in type_names:
            _advance(progress, requested)
            try:
                outcome = _generate_one(
                    catalog, requested, wanted, out, force, skip_existing
                )
            except UserError as error:
                failed.append(f"{requested}: {error}")
                typer.echo(f"failed {requested}: {error}", err=True)
                continue
            written += outcome.startswith("wrote")
            typer.echo(outcome)
    write_schema(out)
    if failed:
        raise UserError(
            f"generated {written} of {len(type_names)} types; failed: "
            + "; ".join(failed)
        )


def _generate_one(
    catalog: EsiCatalog,
    requested: str,
    revision: int | None,
    out: Path,
    force: bool,
    skip_existing: bool,
) -> str:
    """Write one type's file; the line to print, or a UserError."""
    entry = catalog.find(requested, revision)
    name = entry.type_name
    path = file_in(out, terminal_file_name(name))
    if path.exists() and skip_existing and not force:
        return f"kept {path} ({name})"
    if path.exists() and not force:
        raise UserError(
            f"{path.name} exists: `terminals regenerate {out}` keeps its choices, "
            "--force overwrites them",
            path=path,
        )
    from fastcs_ethercat.terminals.saving import write_whole

    terminal = terminal_from_esi(catalog.load(name, entry.revision))
    write_whole(path, terminal_file_text({name: terminal}))
    return f"wrote {path} ({name} revision 0x{entry.revision:08x})"


@terminals_app.command("regenerate")
def regenerate(
    directory: Annotated[
        Path, typer.Argument(metavar="DIR", help="Directory of terminal YAML files.")
    ],
    esi: EsiOption = None,
    keep_revision: Annotated[
        bool,
        typer.Option("--keep-revision", help="Stay on each file's revision."),
    ] = False,
    revisions: Annotated[
        list[str] | None,
        typer.Option(
            "--revision",
            metavar="TYPE=REV",
            help="Move TYPE to revision REV (repeatable); without it a file "
            "only moves to the newest revision of its own lineage.",
        ),
    ] = None,
) -> None:
    """Regenerate every YAML in DIR from ESI, keeping the engineer's choices
    and comments; prints what changed."""
    from fastcs_ethercat.terminals.saving import save_terminals

    paths = terminal_paths([directory])
    files = {path: read_terminal_file(path) for path in paths}
    requested = _type_revisions(revisions or [])
    catalog = _catalog(esi)
    total = sum(len(types) for types in files.values())
    reports: list[ChangeReport] = []
    notes: list[str] = []
    unchanged: list[str] = []
    written = 0
    with _progress("regenerating", total) as progress:
        for path, types in files.items():
            merged_types: dict[str, TerminalType] = {}
            for name, old in types.items():
                _advance(progress, name)
                merged, report, note = _regenerate_one(
                    catalog, name, old, requested.pop(name, None), keep_revision
                )
                merged_types[name] = merged
                if report is not None:
                    reports.append(report)
                elif note:
                    unchanged.append(f"{name} ({path}): {note}")
                if report is not None and note:
                    notes.append(f"{name} ({path.name}): {note}")
            saved = save_terminals(path, merged_types)
            written += saved.changed
            notes += [f"{path}: {dropped}" for dropped in saved.dropped]
    write_schema(directory)
    for report in reports:
        typer.echo(report.summary())
        for line in report.lines():
            typer.echo(f"  {line}")
    for note in notes:
        typer.echo(f"note: {note}")
    typer.echo(f"regenerated {len(reports)} terminal types; {written} files changed")
    if requested:
        raise UserError(
            f"--revision names types not in {directory}: {', '.join(requested)}"
        )
    if unchanged:
        raise UserError("left unchanged: " + "; ".join(unchanged), path=directory)


def _type_revisions(items: list[str]) -> dict[str, int]:
    """`EL3104=0x00110000` options as {type: revision}."""
    result: dict[str, int] = {}
    for item in items:
        name, sep, number = item.partition("=")
        revision = _revision(number) if sep and name else None
        if revision is None:
            raise UserError(f"--revision {item!r}: want TYPE=REV (EL3104=0x00110000)")
        result[name] = revision
    return result


def _regenerate_one(
    catalog: EsiCatalog,
    name: str,
    old: TerminalType,
    requested: int | None,
    keep_revision: bool,
) -> tuple[TerminalType, ChangeReport | None, str | None]:
    """The merged terminal, its report and a note; the old one when it stays."""
    if name not in catalog.type_names():
        return old, None, "not in the ESI files, left unchanged"
    choice = regenerate_revision(
        catalog, name, old, requested=requested, keep_revision=keep_revision
    )
    if choice.entry is None:
        return old, None, f"left unchanged: {choice.note}"
    fresh = terminal_from_esi(catalog.load(name, choice.entry.revision))
    merged, report = merge_terminal(name, old, fresh)
    return merged, report, choice.note


FileArgument = Annotated[
    Path, typer.Argument(metavar="FILE", help="Terminal YAML file.")
]
TypeOption = Annotated[
    str | None,
    typer.Option("--type", help="Terminal type, if the file holds several."),
]
OffOption = Annotated[bool, typer.Option("--off", help="Deselect instead of select.")]


def _edit_file(
    file: Path, type_name: str | None, edit: Callable[[TerminalType], TerminalType]
) -> tuple[str, TerminalType]:
    """Apply `edit` to one type of a file and save it (comments kept)."""
    from fastcs_ethercat.terminals.saving import save_terminals

    types = read_terminal_file(file)
    name = _one_type(types, type_name, file)
    try:
        changed = edit(types[name])
    except SelectionError as error:
        raise UserError(str(error), path=file, where=name) from None
    types[name] = changed
    saved = save_terminals(file, types)
    for dropped in saved.dropped:
        typer.echo(f"note: {file}: {dropped}", err=True)
    return name, changed


@terminals_app.command("select-group")
def select_group_command(
    file: FileArgument,
    group: Annotated[str, typer.Argument(metavar="GROUP", help="PDO group name.")],
    type_name: TypeOption = None,
) -> None:
    """Select a PDO group and switch the symbols' `selected` flags with it."""
    chosen: list[str] = []

    def edit(terminal: TerminalType) -> TerminalType:
        chosen.append(group_name(terminal, group))
        return select_group(terminal, chosen[0])

    name, changed = _edit_file(file, type_name, edit)
    on = sum(node.selected for node in changed.symbol_nodes)
    typer.echo(
        f"{name}: selected PDO group {chosen[0]!r} "
        f"({on} of {len(changed.symbol_nodes)} symbol nodes selected)"
    )


@terminals_app.command("select")
def select_command(
    file: FileArgument,
    symbols: Annotated[
        list[str],
        typer.Argument(
            metavar="SYMBOL...",
            help="Symbols by name_template ('AI Standard Channel {channel}') "
            "or fastcs_name.",
        ),
    ],
    off: OffOption = False,
    type_name: TypeOption = None,
) -> None:
    """Select symbols (PVs are made for them), or deselect them with --off."""
    name, changed = _edit_file(
        file, type_name, lambda terminal: select_symbols(terminal, symbols, not off)
    )
    on = [node.name_template for node in changed.symbol_nodes if node.selected]
    typer.echo(f"{name}: {len(on)} of {len(changed.symbol_nodes)} symbols selected")


@terminals_app.command("coe")
def coe_command(
    file: FileArgument,
    targets: Annotated[
        list[str],
        typer.Argument(
            metavar="INDEX[:SUB]...",
            help="CoE objects (0x8000) or sub-indices (0x8000:11), hex.",
        ),
    ],
    off: OffOption = False,
    type_name: TypeOption = None,
) -> None:
    """Select CoE objects or sub-indices (PVs are made for them), or --off."""
    name, changed = _edit_file(
        file, type_name, lambda terminal: select_coe(terminal, targets, not off)
    )
    on = [obj for obj in changed.coe_objects if obj.selected]
    typer.echo(f"{name}: {len(on)} of {len(changed.coe_objects)} CoE objects selected")


SymbolArgument = Annotated[
    str,
    typer.Argument(
        metavar="SYMBOL",
        help="Symbol by name_template ('AI Standard Channel {channel}') or "
        "fastcs_name.",
    ),
]
MemberOption = Annotated[
    str | None,
    typer.Option(
        "--member",
        help="Member by name ('Value', 'Status.Error'; also 'Status__Error') or "
        "fastcs_name; "
        "default: the symbol's one value (units) or status bit (severity).",
    ),
]


@terminals_app.command("units")
def units_command(
    file: FileArgument,
    symbol: SymbolArgument,
    member: MemberOption = None,
    scale: Annotated[
        float | None, typer.Option(help="Engineering value per count.")
    ] = None,
    offset: Annotated[
        float | None, typer.Option(help="Engineering value at count 0.")
    ] = None,
    unit: Annotated[str | None, typer.Option(help="EGU, e.g. V, mA, degC.")] = None,
    precision: Annotated[
        int | None, typer.Option(help="Decimals shown (PREC).")
    ] = None,
    reset: Annotated[
        bool,
        typer.Option("--reset", help="Drop the overrides: back to the dscale's."),
    ] = False,
    type_name: TypeOption = None,
) -> None:
    """Set (or show) the engineering units a member's value is served in:
    raw * scale + offset, in UNIT with PRECISION decimals; each option
    overrides what the member's ESI dscale gives, the others stay."""
    wanted = (scale, offset, unit, precision)
    if any(value is not None for value in wanted) or reset:

        def edit(terminal: TerminalType) -> TerminalType:
            return set_units(
                terminal,
                symbol,
                member,
                scale=scale,
                offset=offset,
                unit=unit,
                precision=precision,
                reset=reset,
            )

        name, terminal = _edit_file(file, type_name, edit)
    else:
        name, terminal = _read_one(file, type_name)
    node, chosen = _member_of(file, name, terminal, symbol, member)
    scaling = member_scaling(chosen)
    served = scaling.text() if scaling is not None else "raw counts"
    origin = f"dscale {chosen.dscale}" if chosen.dscale else "no dscale"
    overridden = [key for key in UNIT_CHOICES if getattr(chosen, key) is not None]
    if overridden:
        origin += f"; set here: {', '.join(overridden)}"
    typer.echo(f"{name}: {node.name_template}.{chosen.shown_name}: {served} ({origin})")


@terminals_app.command("severity")
def severity_command(
    file: FileArgument,
    symbol: SymbolArgument,
    level: Annotated[
        str,
        typer.Argument(
            metavar="LEVEL",
            help="none, minor or major while the bit or field is set; "
            "default: what its name implies.",
        ),
    ],
    member: MemberOption = None,
    type_name: TypeOption = None,
) -> None:
    """Set the alarm severity a status bit or field raises while it is set."""
    levels: dict[str, SeverityName | None] = {
        "none": "none",
        "minor": "minor",
        "major": "major",
        "default": None,
    }
    if level.lower() not in levels:
        raise UserError(
            f"severity {level!r}: choose none, minor, major or default", path=file
        )
    severity = levels[level.lower()]
    name, terminal = _edit_file(
        file,
        type_name,
        lambda terminal: set_severity(terminal, symbol, member, severity),
    )
    node, chosen = _member_of(file, name, terminal, symbol, member, status=True)
    effective = member_severity(chosen, node.direction)
    how = "set" if chosen.severity is not None else "from its name"
    typer.echo(f"{name}: {node.name_template}.{chosen.shown_name}: {effective} ({how})")


def _read_one(file: Path, type_name: str | None) -> tuple[str, TerminalType]:
    types = read_terminal_file(file)
    name = _one_type(types, type_name, file)
    return name, types[name]


def _member_of(
    file: Path,
    name: str,
    terminal: TerminalType,
    symbol: str,
    member: str | None,
    *,
    status: bool = False,
) -> tuple[Any, Any]:
    """The symbol node and member a `units` / `severity` command names."""
    try:
        node = terminal.symbol_nodes[find_symbol(terminal, symbol)]
        return node, node.members[find_member(node, member, status)]
    except SelectionError as error:
        raise UserError(str(error), path=file, where=name) from None


@terminals_app.command("edit")
def edit_command(
    directory: Annotated[
        Path,
        typer.Argument(metavar="[DIR]", help="Directory of terminal YAML files."),
    ] = Path("terminals"),
    esi: EsiOption = None,
    target: TargetOption = None,
    ams_net_id: AmsNetIdOption = None,
    host: Annotated[
        str,
        typer.Option(
            "--host",
            help="Address to serve on (default loopback; any other address "
            "needs the token printed at start, or $FASTCS_ETHERCAT_EDITOR_TOKEN).",
        ),
    ] = LOOPBACK,
    port: Annotated[
        int, typer.Option("--port", help="Port to serve on (0: any free one).")
    ] = 8080,
) -> None:
    """A web editor for the terminal files of DIR: PDO group, symbols, CoE
    objects, oversampling, names, a diff before saving.

    With --target (TwinCAT or the simulator) it shows each live terminal's
    PDO group.
    """
    from fastcs_ethercat.editor.server import run_editor

    run_editor(directory, esi, target, host, port, ams_net_id)


@terminals_app.command("import")
def import_command(
    file: Annotated[
        Path, typer.Argument(metavar="FILE", help="catio-terminals terminal_types.yaml")
    ],
    out: Annotated[Path, typer.Option("--out", help="Directory for the YAML files.")],
    esi: EsiOption = None,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite existing files.")
    ] = False,
) -> None:
    """Convert a catio-terminals file: every type is generated from the ESI of
    its own identity and takes over catio's selections and fastcs_names;
    every node or choice that cannot be placed is named."""
    from fastcs_ethercat.terminals.catio_import import import_catio, read_catio_file
    from fastcs_ethercat.terminals.saving import write_whole

    located, types = read_catio_file(file)
    catalog = _catalog(esi)
    out.mkdir(parents=True, exist_ok=True)
    failed: list[str] = []
    unplaced = 0
    for result in import_catio(located, types, catalog):
        for problem in result.problems:
            typer.echo(f"warning: {file}: {result.type_name}: {problem}", err=True)
        if result.terminal is None:
            failed.append(result.type_name)
            continue
        unplaced += len(result.problems)
        path = file_in(out, terminal_file_name(result.type_name))
        if path.exists() and not force:
            typer.echo(f"warning: {path} exists (--force overwrites it)", err=True)
            failed.append(result.type_name)
            continue
        write_whole(path, terminal_file_text({result.type_name: result.terminal}))
        typer.echo(f"wrote {path} ({result.type_name})")
    write_schema(out)
    typer.echo(
        f"imported {len(types) - len(failed)} of {len(types)} types; "
        f"{unplaced} nodes or choices could not be placed"
    )
    if failed:
        raise UserError(f"not imported: {', '.join(failed)}", path=file)


def _one_type(types: dict[str, TerminalType], wanted: str | None, file: Path) -> str:
    if wanted is not None:
        if wanted not in types:
            raise UserError(f"no terminal type {wanted!r} in this file", path=file)
        return wanted
    if len(types) != 1:
        raise UserError(
            f"the file holds {len(types)} terminal types; choose one with --type",
            path=file,
        )
    return next(iter(types))


@terminals_app.command("check")
def check(
    paths: Annotated[
        list[str], typer.Argument(metavar="PATH...", help="YAML files, dirs or globs.")
    ],
) -> None:
    """Validate terminal YAML files and report how many types they hold
    (none is an error: a check that found nothing checked nothing)."""
    registry = load_terminals(paths)
    if not len(registry):
        raise UserError(f"no terminal types found in {' '.join(paths)}")
    typer.echo(f"{len(registry)} terminal types OK")


@terminals_app.command("schema")
def schema(
    out: Annotated[
        Path | None, typer.Option("--out", help="Write here instead of stdout.")
    ] = None,
) -> None:
    """Print (or write) the JSON schema of terminal YAML files."""
    text = schema_text()
    if out is None:
        typer.echo(text, nl=False)
    else:
        out.write_text(text, encoding="utf-8")
        typer.echo(f"wrote {out}")


@terminals_app.command("update-cache")
def update_cache(
    url: Annotated[
        str, typer.Option("--url", help="Where to download the ESI zip from.")
    ] = VENDOR_ZIP_URL,
) -> None:
    """Download Beckhoff_EtherCAT_XML.zip into the cache (XDG_CACHE_HOME)."""
    console = _stderr()
    progress = Progress(
        TextColumn("downloading"),
        BarColumn(),
        DownloadColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    with progress:
        task = progress.add_task("download", total=None)

        def report(done: int, total: int | None) -> None:
            progress.update(task, completed=done, total=total)

        path = download_vendor_zip(url, cached_zip(), report)
    typer.echo(f"cached {path}")
