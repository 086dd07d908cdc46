"""`fastcs-ethercat terminals`: ESI XML to terminal YAML.

Commands: list, show, generate, regenerate, select-group, check, schema,
update-cache. Results go to stdout; progress bars go to stderr; user errors
are raised as `UserError` (one line, exit code 2, printed by the root app).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
)

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.esi.model import EsiDevice, parse_esi_int
from fastcs_ethercat.terminals.esi_sources import (
    VENDOR_ZIP_URL,
    cached_zip,
    download_vendor_zip,
    open_catalog,
)
from fastcs_ethercat.terminals.files import (
    CATIO_LAYOUT_KEY,
    read_terminal_file,
    terminal_file_name,
    terminal_file_text,
)
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.loader import load_terminals, terminal_paths
from fastcs_ethercat.terminals.merge import ChangeReport, merge_terminal
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.schema import schema_text, write_schema
from fastcs_ethercat.terminals.selection import UnknownGroupError, select_group

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
    return catalog


@terminals_app.command("list")
def list_types(
    esi: EsiOption = None,
    filter_glob: Annotated[
        str | None,
        typer.Option("--filter", help="Only types matching this glob (EL31*)."),
    ] = None,
) -> None:
    """One line per terminal type: newest revision, product code, group type."""
    catalog = _catalog(esi)
    shown = 0
    for entry in catalog.newest():
        if filter_glob and not fnmatch.fnmatchcase(
            entry.type_name.upper(), filter_glob.upper()
        ):
            continue
        groups = "yes" if entry.has_pdo_groups else "no"
        typer.echo(
            f"{entry.type_name:<16} revision=0x{entry.revision:08x} "
            f"product_code=0x{entry.product_code:08x} "
            f"group_type={entry.group_type or '-'} pdo_groups={groups}"
        )
        shown += 1
    typer.echo(f"{shown} terminal types")


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
    revisions = [f"0x{e.revision:08x}" for e in catalog.revisions(device.type_name)]
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
    """Generate one YAML file per terminal type (default choices)."""
    catalog = _catalog(esi)
    wanted = _revision(revision)
    out.mkdir(parents=True, exist_ok=True)
    planned: list[tuple[str, Path]] = []
    for requested in type_names:
        name = catalog.find(requested, wanted).type_name
        path = out / terminal_file_name(name)
        if path.exists() and skip_existing and not force:
            typer.echo(f"kept {path} ({name})")
            continue
        if path.exists() and not force:
            raise UserError(
                f"{path.name} exists: `terminals regenerate {out}` keeps its choices, "
                "--force overwrites them",
                path=path,
            )
        planned.append((name, path))
    with _progress("generating", len(planned)) as progress:
        for name, path in planned:
            device = catalog.load(name, wanted)
            terminal = terminal_from_esi(device)
            path.write_text(terminal_file_text({name: terminal}), encoding="utf-8")
            _advance(progress, name)
    write_schema(out)
    for name, path in planned:
        typer.echo(f"wrote {path} ({name})")


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
) -> None:
    """Regenerate every YAML in DIR from ESI, keeping the engineer's choices."""
    paths = terminal_paths([directory])
    files = {path: read_terminal_file(path) for path in paths}
    catalog = _catalog(esi)
    total = sum(len(types) for types in files.values())
    reports: list[ChangeReport] = []
    missing: list[str] = []
    known = set(catalog.type_names())
    written = 0
    with _progress("regenerating", total) as progress:
        for path, types in files.items():
            if not _our_layout(path):
                raise UserError(
                    "catio-terminals layout: generate our files with "
                    "`terminals generate` instead",
                    path=path,
                )
            merged_types: dict[str, TerminalType] = {}
            for name, old in types.items():
                _advance(progress, name)
                if name not in known:
                    missing.append(f"{name} ({path})")
                    merged_types[name] = old
                    continue
                revision = old.identity.revision_number if keep_revision else None
                fresh = terminal_from_esi(catalog.load(name, revision))
                merged, report = merge_terminal(name, old, fresh)
                merged_types[name] = merged
                reports.append(report)
            text = terminal_file_text(merged_types)
            if text != path.read_text(encoding="utf-8"):
                path.write_text(text, encoding="utf-8")
                written += 1
    write_schema(directory)
    for report in reports:
        typer.echo(report.summary())
        for line in report.lines():
            typer.echo(f"  {line}")
    typer.echo(f"regenerated {len(reports)} terminal types; {written} files changed")
    if missing:
        raise UserError(
            f"not in the ESI files, left unchanged: {', '.join(missing)}",
            path=directory,
        )


def _our_layout(path: Path) -> bool:
    """False for catio-terminals' single-file layout (`terminal_types:`)."""
    return not any(
        line.startswith(f"{CATIO_LAYOUT_KEY}:")
        for line in path.read_text(encoding="utf-8").splitlines()
    )


@terminals_app.command("select-group")
def select_group_command(
    file: Annotated[Path, typer.Argument(metavar="FILE", help="Terminal YAML file.")],
    group: Annotated[str, typer.Argument(metavar="GROUP", help="PDO group name.")],
    type_name: Annotated[
        str | None,
        typer.Option("--type", help="Terminal type, if the file holds several."),
    ] = None,
) -> None:
    """Select a PDO group and switch the symbols' `selected` flags with it."""
    types = read_terminal_file(file)
    if not _our_layout(file):
        raise UserError("catio-terminals layout is read-only here", path=file)
    name = _one_type(types, type_name, file)
    terminal = types[name]
    chosen = _group_name(terminal, group)
    try:
        changed = select_group(terminal, chosen)
    except UnknownGroupError as error:
        raise UserError(str(error), path=file, where=name) from None
    types[name] = changed
    file.write_text(terminal_file_text(types), encoding="utf-8")
    on = sum(node.selected for node in changed.symbol_nodes)
    typer.echo(
        f"{name}: selected PDO group {chosen!r} "
        f"({on} of {len(changed.symbol_nodes)} symbol nodes selected)"
    )


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


def _group_name(terminal: TerminalType, wanted: str) -> str:
    """`wanted`, or the one group whose name matches it ignoring case."""
    names = [g.name for g in terminal.pdo_groups]
    if wanted in names:
        return wanted
    folded = [n for n in names if n.casefold() == wanted.casefold()]
    return folded[0] if len(folded) == 1 else wanted


@terminals_app.command("check")
def check(
    paths: Annotated[
        list[str], typer.Argument(metavar="PATH...", help="YAML files, dirs or globs.")
    ],
) -> None:
    """Validate terminal YAML files (either layout) and report what they hold."""
    registry = load_terminals(paths)
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
