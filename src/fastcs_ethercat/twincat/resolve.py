"""Chain + terminal YAML -> the concrete system: names, addresses, NetIds,
identities and each terminal's active configuration.

Defaults follow TwinCAT: masters are `Device <n> (EtherCAT)` with the system
NetId's 5th byte set to n + 1 (facts section 6, catio's dumps); slaves are
`Term <k> (<type>)` numbered across the whole project and get EtherCAT
addresses 1001, 1002, ... in bus order (real rack dumps).

A slave is played from its type's YAML, or, when the chain gives it another
revision, from the YAML of that revision among `revisions` (other revisions
of the types, matched by product code and revision): a terminal's symbols
are those of the revision it reports. Without such a file the type's YAML
is played and a note says so (`SimTarget.notes`). A type without YAML that
gives its `product_code` is played with its identity only.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from fastcs_ethercat.ads.ethercat import AlState, SlaveIdentity
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.chain.file import Chain, MasterSpec, SlaveSpec
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals.files import terminal_file_name
from fastcs_ethercat.terminals.load_cache import read_terminal_file_cached
from fastcs_ethercat.terminals.loader import load_terminals, terminal_paths
from fastcs_ethercat.terminals.model import Identity, TerminalType
from fastcs_ethercat.terminals.registry import TerminalRegistry
from fastcs_ethercat.terminals.symbols import ExpandedSymbol, expanded_symbols

FIRST_SLAVE_ADDRESS: Final = 1001
"""EtherCAT address of the first slave of a master (TwinCAT's default)."""
BECKHOFF_VENDOR_ID: Final = 2

Revisions = Mapping[tuple[int, int], TerminalType]
"""Terminal YAML of other revisions by (product code, revision number)."""


@dataclass(frozen=True, slots=True)
class ResolvedSlave:
    """One slave as the simulator runs it."""

    position: int
    """0-based position on its master's bus."""
    name: str
    type_name: str
    address: int
    identity: SlaveIdentity
    terminal: TerminalType
    """The YAML description with the chain's PDO group / factor applied."""
    spec: SlaveSpec
    initial_state: AlState
    note: str = ""
    """Why its process data is not that of the revision it reports ("": it is)."""

    def active_symbols(self) -> list[ExpandedSymbol]:
        """The symbols of the active PDO configuration, per channel.

        Without PDO groups every PDO is assigned. With groups, TwinCAT assigns
        exactly the PDOs of the selected group (the ESI's
        `AlternativeSmMapping`): a PDO in no group is not assigned (ELM3704's
        `PAI Samples 2 Channel 1`, `PAI Control Channel 1` have no default
        sync manager and are in no mapping). This is the heart of dynamic PDOs.
        """
        terminal = self.terminal
        symbols = expanded_symbols(terminal)
        active = terminal.active_group
        if active is None:
            return symbols
        pdos = set(active.pdo_indices)
        nodes = set(active.symbol_indices)
        return [
            symbol
            for symbol in symbols
            if (
                symbol.pdo_index in pdos
                if symbol.pdo_index is not None and pdos
                else symbol.node_index in nodes
            )
        ]

    @property
    def has_mailbox(self) -> bool:
        """Terminals with a CoE dictionary answer SDO requests."""
        return bool(self.terminal.coe_objects)


@dataclass(frozen=True, slots=True)
class ResolvedMaster:
    """One EtherCAT master (I/O device) and its slaves in bus order."""

    index: int
    device_id: int
    name: str
    net_id: AmsNetId
    info_data: bool
    slaves: tuple[ResolvedSlave, ...]


def resolve_chain(
    chain: Chain,
    terminals: TerminalRegistry | Path | str,
    revisions: Revisions | None = None,
) -> tuple[AmsNetId, tuple[ResolvedMaster, ...]]:
    """The system NetId and every master with its slaves, checked against the
    terminal YAML (unknown types, PDO groups and factors are UserErrors)."""
    registry = (
        terminals
        if isinstance(terminals, TerminalRegistry)
        else load_terminals([Path(terminals)])
    )
    system_net_id = AmsNetId.parse(chain.system.net_id)
    masters: list[ResolvedMaster] = []
    term_number = 1
    for m, master in enumerate(chain.masters):
        slaves: list[ResolvedSlave] = []
        for s, slave in enumerate(master.slaves):
            slaves.append(
                _resolve_slave(
                    chain, registry, revisions or {}, (m, s), slave, term_number
                )
            )
            term_number += 1
        masters.append(
            ResolvedMaster(
                index=m,
                device_id=m + 1,
                name=master.name or f"Device {m + 1} (EtherCAT)",
                net_id=_master_net_id(master, system_net_id, m),
                info_data=master.info_data,
                slaves=tuple(slaves),
            )
        )
    _check_unique(chain, system_net_id, masters)
    return system_net_id, tuple(masters)


def _master_net_id(master: MasterSpec, system: AmsNetId, index: int) -> AmsNetId:
    if master.net_id is not None:
        return AmsNetId.parse(master.net_id)
    return system.with_octet(4, index + 2)


def _resolve_slave(
    chain: Chain,
    registry: TerminalRegistry,
    revisions: Revisions,
    where: tuple[int, int],
    spec: SlaveSpec,
    term_number: int,
) -> ResolvedSlave:
    m, s = where
    loc = ("masters", m, "slaves", s)
    name = spec.name or f"Term {term_number} ({spec.type})"
    terminal, note = _terminal_of(chain, registry, revisions, loc, spec)
    terminal = _with_pdo_group(chain, loc, spec, terminal)
    terminal = _with_oversampling(chain, loc, spec, terminal)
    identity = terminal.identity
    return ResolvedSlave(
        position=s,
        name=name,
        type_name=spec.type,
        address=FIRST_SLAVE_ADDRESS + s,
        identity=SlaveIdentity(
            vendor_id=identity.vendor_id,
            product_code=identity.product_code,
            revision=spec.revision
            if spec.revision is not None
            else identity.revision_number,
            serial_number=spec.serial,
        ),
        terminal=terminal,
        spec=spec,
        initial_state=AlState[spec.al_state],
        note=f"{name}: {note}" if note else "",
    )


def _terminal_of(
    chain: Chain,
    registry: TerminalRegistry,
    revisions: Revisions,
    loc: tuple[object, ...],
    spec: SlaveSpec,
) -> tuple[TerminalType, str]:
    """The description a slave is played from, and a note when it is not
    that of the revision the slave reports."""
    if spec.type not in registry:
        if spec.product_code is not None:
            return _bare_terminal(spec), ""
        known = ", ".join(registry.type_names()) or "none"
        raise chain.error(
            (*loc, "type"),
            f"unknown terminal type {spec.type!r} (known: {known}; a type "
            "without YAML needs its product_code)",
        )
    terminal = registry.get(spec.type).terminal
    identity = terminal.identity
    for key in ("vendor_id", "product_code"):
        given = getattr(spec, key)
        if given is not None and given != getattr(identity, key):
            raise chain.error(
                (*loc, key),
                f"{spec.type}'s YAML has {key} 0x{getattr(identity, key):08x}, "
                f"not 0x{given:08x}",
            )
    if spec.revision is None or spec.revision == identity.revision_number:
        return terminal, ""
    other = revisions.get((identity.product_code, spec.revision))
    if other is not None:
        return other, ""
    return terminal, (
        f"no YAML of {spec.type} revision 0x{spec.revision:08x} (sim --revisions "
        f"DIR); its process data is that of revision "
        f"0x{identity.revision_number:08x}"
    )


def _bare_terminal(spec: SlaveSpec) -> TerminalType:
    """A type with no YAML: its identity, no process data, no CoE."""
    assert spec.product_code is not None
    return TerminalType(
        identity=Identity(
            vendor_id=BECKHOFF_VENDOR_ID if spec.vendor_id is None else spec.vendor_id,
            product_code=spec.product_code,
            revision_number=spec.revision or 0,
        ),
        description=f"{spec.type} (no terminal YAML: identity only)",
        symbol_nodes=[],
        coe_objects=[],
    )


def load_revisions(
    sources: Iterable[Path | str],
) -> dict[tuple[int, int], TerminalType]:
    """Terminal YAML of other revisions (files, directories, globs), by
    (product code, revision number); a type may have any number of files."""
    found: dict[tuple[int, int], TerminalType] = {}
    for path in terminal_paths(sources):
        for type_name, terminal in read_terminal_file_cached(path).items():
            identity = terminal.identity
            key = (identity.product_code, identity.revision_number)
            if key in found:
                raise UserError(
                    f"{type_name} revision 0x{key[1]:08x} is described twice",
                    path=path,
                    where=type_name,
                )
            found[key] = terminal
    return found


def _with_pdo_group(
    chain: Chain, loc: tuple[object, ...], spec: SlaveSpec, terminal: TerminalType
) -> TerminalType:
    if spec.pdo_group is None:
        return terminal
    names = [group.name for group in terminal.pdo_groups]
    if spec.pdo_group not in names:
        offered = ", ".join(repr(n) for n in names) or "none (static PDOs)"
        raise chain.error(
            (*loc, "pdo_group"),
            f"{spec.type} has no PDO group {spec.pdo_group!r} (groups: {offered})",
        )
    return terminal.model_copy(update={"selected_pdo_group": spec.pdo_group})


def _with_oversampling(
    chain: Chain, loc: tuple[object, ...], spec: SlaveSpec, terminal: TerminalType
) -> TerminalType:
    oversampling = terminal.oversampling
    active = terminal.active_group
    if oversampling is not None and oversampling.by_group and active is not None:
        factor = active.oversampling_factor or oversampling.selected_factor
        if spec.oversampling is not None and spec.oversampling != factor:
            raise chain.error(
                (*loc, "oversampling"),
                f"{spec.type} takes its factor from the PDO group "
                f"({active.name!r} has {factor}); choose the group instead",
            )
        updated = oversampling.model_copy(update={"selected_factor": factor})
        return terminal.model_copy(update={"oversampling": updated})
    if spec.oversampling is None:
        return terminal
    if oversampling is None:
        raise chain.error(
            (*loc, "oversampling"), f"{spec.type} is not an oversampling terminal"
        )
    if oversampling.factors and spec.oversampling not in oversampling.factors:
        offered = ", ".join(str(f) for f in oversampling.factors)
        raise chain.error(
            (*loc, "oversampling"),
            f"{spec.type} offers oversampling factors {offered}, "
            f"not {spec.oversampling}",
        )
    updated = oversampling.model_copy(update={"selected_factor": spec.oversampling})
    return terminal.model_copy(update={"oversampling": updated})


def _check_unique(
    chain: Chain, system: AmsNetId, masters: list[ResolvedMaster]
) -> None:
    """NetIds and names must not collide (TwinCAT would not allow it)."""
    net_ids = {system: "the system"}
    names: dict[str, str] = {}
    for master in masters:
        loc = ("masters", master.index)
        if master.net_id in net_ids:
            raise chain.error(
                (*loc, "net_id"),
                f"NetId {master.net_id} is already used by {net_ids[master.net_id]}",
            )
        net_ids[master.net_id] = master.name
        for slave in (master.name, *(s.name for s in master.slaves)):
            if slave in names:
                raise chain.error(loc, f"name {slave!r} is used twice")
            names[slave] = master.name


def chain_registry(chain: Chain) -> TerminalRegistry | None:
    """The YAML of the chain's own `terminal_dirs` (None: it names none); a
    folder that is not there is a `UserError` naming the chain's line."""
    sources = chain.terminal_sources()
    if sources is None:
        return None
    try:
        return load_terminals(sources)
    except UserError as error:
        raise chain.error(("terminal_dirs",), str(error)) from None


def revisions_of(registry: TerminalRegistry) -> dict[tuple[int, int], TerminalType]:
    """Every YAML of `registry` by (product code, revision): a slave of
    another revision than its type's first YAML is played from its own."""
    found: dict[tuple[int, int], TerminalType] = {}
    for item in registry:
        identity = item.terminal.identity
        found[(identity.product_code, identity.revision_number)] = item.terminal
    return found


def registry_for(
    terminals_dir: Path | str, types: Iterable[str] | None = None
) -> TerminalRegistry:
    """The terminal types of a directory of YAML files.

    With `types`, only their files (`<type>.yaml`, one file per type) are
    read when all exist, which keeps start-up fast; otherwise every file.
    """
    path = Path(terminals_dir)
    if not path.is_dir():
        raise UserError("no such terminal directory", path=path)
    if types is not None:
        wanted = [path / terminal_file_name(name) for name in sorted(set(types))]
        if all(file.is_file() for file in wanted):
            return load_terminals(wanted)
    return load_terminals([path])


__all__ = [
    "FIRST_SLAVE_ADDRESS",
    "ResolvedMaster",
    "ResolvedSlave",
    "Revisions",
    "chain_registry",
    "load_revisions",
    "registry_for",
    "resolve_chain",
    "revisions_of",
]
