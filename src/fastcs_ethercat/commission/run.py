"""`fastcs-ethercat init`, step by step: discover, describe, select, write,
serve, summarise; on a DIR written before, what changed on the rack.

Progress goes to `say` (the command's stderr); the `Outcome` is what
`summary` prints. Every refusal is a `UserError` (one line, DIR untouched:
everything is written in a folder beside DIR that takes its place only at
the end).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fastcs_ethercat.commission import layout, writing
from fastcs_ethercat.commission.discover import discover_rack
from fastcs_ethercat.commission.rack import (
    RackChange,
    RackSlave,
    rack_changes,
    rack_slaves,
)
from fastcs_ethercat.commission.served import Served
from fastcs_ethercat.commission.sources import (
    Described,
    Describer,
    Origin,
    discovery_registry,
    file_names,
    group_by_identity,
    slave_identity,
)
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.ioc.config import IocConfig, load_ioc_config
from fastcs_ethercat.ioc.plan import SystemPlan, TerminalPlan
from fastcs_ethercat.terminals.registry import RegisteredTerminal, TerminalRegistry

Say = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class InitRequest:
    """The command line of one `init`."""

    settings: layout.Settings
    esi: tuple[Path, ...]
    out: Path
    from_chain: Path | None = None
    check: bool = False


@dataclass(slots=True)
class Outcome:
    """What a run found: the summary's content."""

    plan: SystemPlan
    described: list[Described]
    served: Served
    changes: list[RackChange]
    decisions: list[str]
    differences: list[str]
    first_run: bool


def run_init(request: InitRequest, say: Say) -> Outcome:
    """Everything `init` does; DIR is replaced only when not `check`."""
    out = request.out
    layout.check_out_dir(out)
    for source in request.esi:
        if not source.exists():
            raise UserError("no such ESI file or directory", path=source)
    if request.from_chain is not None and not request.from_chain.is_file():
        raise UserError("no such chain file", path=request.from_chain)
    config = _discovery_config(request.settings)
    before = _earlier_rack(out)
    kept = _kept_terminals(out)
    shipped = _shipped_terminals()
    describer = Describer(kept, shipped, lambda: _open_catalog(request.esi, say))
    registry = discovery_registry(kept, shipped)
    if request.from_chain is not None:
        registry = _playable(registry, request.from_chain, describer, out)
    where = request.from_chain or config.target
    say(f"discovering {where}")
    plan = discover_rack(config, registry, request.from_chain)
    terminals = _terminals(plan)
    say(f"found {len(terminals)} terminals on {len(plan.masters)} master(s)")
    described = _describe(describer, terminals, say)
    file_names(described)
    if any(d.origin in (Origin.GENERATED, Origin.NEAREST) for d in described):
        say(f"discovering {where} again: the PDO groups by the generated YAML")
        plan = discover_rack(config, _registry(described, out), request.from_chain)
        _assign(described, _terminals(plan))
    after = _rack(plan)
    changes = rack_changes(before, after) if before is not None else []
    with layout.staging(out) as folder:
        decisions = writing.write_terminals(folder, described, changes)
        writing.write_chain(folder, plan, config.prefix)
        writing.write_config(folder, request.settings)
        say("building the IOC's PVs, screens and PV lists")
        served = writing.serve(folder)
        writing.write_instance(folder, request.settings)
        differences = layout.differences(out, folder)
        if not request.check:
            layout.commit(folder, out)
    return Outcome(
        plan=plan,
        described=described,
        served=served,
        changes=changes,
        decisions=[
            *decisions,
            *_undescribed(described),
            *_unused(kept, described),
            *_config_notes(request),
        ],
        differences=differences,
        first_run=before is None,
    )


def _discovery_config(settings: layout.Settings) -> IocConfig:
    if (settings.route_user is None) != (settings.password_env is None):
        raise UserError("give --route-user and --password-env together")
    overrides: dict[str, Any] = {
        "prefix": settings.prefix,
        "target": settings.target,
        "ams_net_id": settings.ams_net_id,
    }
    if settings.route_user is not None:
        overrides["route.user"] = settings.route_user
        overrides["route.password_env"] = settings.password_env
    return load_ioc_config(None, overrides)


def _earlier_rack(out: Path) -> list[RackSlave] | None:
    """The rack of DIR's chain.yaml (None on a first run)."""
    path = out / layout.CHAIN_FILE
    if not path.is_file():
        return None
    from fastcs_ethercat.chain.file import load_chain

    return rack_slaves(load_chain(path))


def _kept_terminals(out: Path) -> list[RegisteredTerminal]:
    folder = out / layout.TERMINALS_DIR
    if not folder.is_dir():
        return []
    from fastcs_ethercat.terminals.loader import load_terminals

    return list(load_terminals([folder], use_cache=False))


def _shipped_terminals() -> list[RegisteredTerminal]:
    from fastcs_ethercat.shipped import BUILTIN_TERMINALS_DIR
    from fastcs_ethercat.terminals.loader import load_terminals

    return list(load_terminals([BUILTIN_TERMINALS_DIR]))


def _playable(
    registry: TerminalRegistry, path: Path, describer: Describer, out: Path
) -> TerminalRegistry:
    """`registry` with the ESI's YAML of the chain file's types it lacks (a
    chain names a type with YAML by its name alone): the chain is played
    from them."""
    from fastcs_ethercat.chain.file import load_chain

    chain = load_chain(path)
    extra: dict[str, RegisteredTerminal] = {}
    for m, master in enumerate(chain.masters):
        for s, spec in enumerate(master.slaves):
            if spec.type in registry or spec.type in extra or spec.product_code:
                continue
            try:
                terminal = describer.by_type_name(spec.type, spec.revision)
            except UserError as error:
                where = chain.where(("masters", m, "slaves", s, "type"))
                raise UserError(
                    f"{spec.type}: no terminal YAML, and the ESI: {error}",
                    path=path,
                    where=where,
                ) from None
            file = out / layout.TERMINALS_DIR / f"{spec.type}.yaml"
            extra[spec.type] = RegisteredTerminal(spec.type, terminal, file)
    if not extra:
        return registry
    return TerminalRegistry([*registry, *extra.values()])


def _open_catalog(esi: Sequence[Path], say: Say) -> EsiCatalog:
    from fastcs_ethercat.terminals.esi_sources import open_catalog

    say(f"reading the ESI catalog of {', '.join(str(path) for path in esi)}")
    return open_catalog(esi)


def _terminals(plan: SystemPlan) -> list[TerminalPlan]:
    return [terminal for master in plan.masters for terminal in master.terminals]


def _describe(
    describer: Describer, terminals: list[TerminalPlan], say: Say
) -> list[Described]:
    grouped = group_by_identity(terminals)
    described: list[Described] = []
    for number, (identity, slaves) in enumerate(grouped.items(), start=1):
        found = describer.describe(identity, slaves)
        if found.origin in (Origin.GENERATED, Origin.NEAREST):
            say(
                f"[{number}/{len(grouped)}] {found.type_name} revision "
                f"0x{identity[2]:08x}: {found.origin.value} ({found.source})"
            )
        described.append(found)
    return described


def _registry(described: list[Described], out: Path) -> TerminalRegistry:
    """The YAML DIR will hold (named by their paths there)."""
    return TerminalRegistry(
        RegisteredTerminal(d.type_name, d.terminal, out / layout.TERMINALS_DIR / name)
        for d in described
        if d.terminal is not None and (name := d.file_name) is not None
    )


def _assign(described: list[Described], terminals: list[TerminalPlan]) -> None:
    """Each description's slaves as the latest discovery saw them."""
    by_identity = {d.identity: d for d in described}
    for d in described:
        d.slaves = []
    for terminal in terminals:
        by_identity[slave_identity(terminal)].slaves.append(terminal)


def _rack(plan: SystemPlan) -> list[RackSlave]:
    from fastcs_ethercat.chain.file import parse_chain

    return rack_slaves(parse_chain(writing.chain_text(plan, "the rack")))


def _unused(kept: list[RegisteredTerminal], described: list[Described]) -> list[str]:
    """DIR's YAML that no terminal on the rack uses now (left in place)."""
    used = {d.file_name for d in described if d.slaves}
    return [
        f"{layout.TERMINALS_DIR}/{item.path.name}: no terminal on the rack uses "
        f"{item.type_name} revision 0x{item.terminal.identity.revision_number:08x} "
        "now; kept (delete it if it is gone for good)"
        for item in kept
        if item.path.name not in used
    ]


def _config_notes(request: InitRequest) -> list[str]:
    """Where DIR's ioc.yaml (the engineer's, kept) says other than the flags."""
    path = request.out / layout.IOC_FILE
    if not path.is_file():
        return []
    config = load_ioc_config(path)
    settings = request.settings
    return [
        f"{path} keeps {key} {ours!r}, not --{key} {given!r}: edit it if that changed"
        for key, ours, given in (
            ("prefix", config.prefix, settings.prefix),
            ("target", config.target, settings.target),
        )
        if ours != given
    ]


def _undescribed(described: list[Described]) -> list[str]:
    """The identities served by something other than their own YAML."""
    found: list[str] = []
    for item in described:
        names = ", ".join(s.slave.name for s in item.slaves[:3])
        label = f"{item.type_name} revision 0x{item.revision:08x} ({names})"
        if item.origin is Origin.OTHER_YAML:
            found.append(
                f"{label}: no ESI of the type; served from {item.source}, matched "
                "by name: give an ESI source that has it"
            )
        elif item.origin is Origin.NONE:
            found.append(
                f"{label}: unknown type (no ESI, no YAML, no process data): "
                "served with its identity and diagnostics only"
            )
    return found
