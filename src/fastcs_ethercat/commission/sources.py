"""The terminal YAML for each type and revision a rack runs, and where it
came from.

For each identity (vendor, product code, revision) on the rack, in order:

1. a YAML already in DIR/terminals of exactly that identity: kept as it is
   (the engineer's choices and comments are theirs);
2. a shipped YAML of exactly that identity: copied, comments and all;
3. the ESI's description of exactly that revision: generated, the usual
   default selection;
4. the ESI's nearest revision of the product code (same variant first, the
   older on a tie, as the IOC matches): its YAML in DIR or shipped, else
   generated; said so either way;
5. no ESI of the type, but a YAML of another revision (in DIR or shipped):
   that one serves it (the IOC matches it by name) and a human must decide;
6. nothing describes it: a slave without process data (a power feed, an
   end terminal) is served by its identity and diagnostics alone and
   noted; one with process data is refused, naming the type, since no PV
   could be made for its values.

The ESI catalog is opened only when a type needs it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi.catalog import EsiCatalog, usable_revisions
from fastcs_ethercat.esi.model import CatalogEntry
from fastcs_ethercat.ioc.plan import TerminalPlan
from fastcs_ethercat.terminals.files import terminal_file_name
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.registry import (
    RegisteredTerminal,
    TerminalRegistry,
    revision_distance,
)

Identity = tuple[int, int, int]
"""(vendor id, product code, revision number)."""


class Origin(StrEnum):
    """Where a terminal YAML came from."""

    KEPT = "kept"
    SHIPPED = "shipped"
    GENERATED = "generated from the ESI"
    NEAREST = "generated from the ESI's nearest revision"
    NEAREST_YAML = "the YAML of the ESI's nearest revision"
    OTHER_YAML = "a YAML of another revision (no ESI of the type)"
    NONE = "no description"


@dataclass(slots=True)
class Described:
    """The YAML chosen for one identity on the rack."""

    identity: Identity
    type_name: str
    origin: Origin
    terminal: TerminalType | None
    file_name: str | None = None
    """Its file in DIR/terminals (None: no file of its own)."""
    text: str | None = None
    """The text to copy as it is (a kept or shipped file), None: generated."""
    source: str = ""
    """Where it came from: a file, or an ESI file and line."""
    slaves: list[TerminalPlan] = field(default_factory=list)

    @property
    def revision(self) -> int:
        return self.identity[2]


def identity_of(terminal: TerminalType) -> Identity:
    ident = terminal.identity
    return (ident.vendor_id, ident.product_code, ident.revision_number)


def slave_identity(plan: TerminalPlan) -> Identity:
    ident = plan.slave.identity
    return (ident.vendor_id, ident.product_code, ident.revision)


def discovery_registry(
    kept: Iterable[RegisteredTerminal], shipped: Iterable[RegisteredTerminal]
) -> TerminalRegistry:
    """DIR's YAML, then the shipped YAML of identities DIR does not describe
    (what the first discovery matches the rack with)."""
    items = list(kept)
    known = {identity_of(item.terminal) for item in items}
    names = {item.type_name: identity_of(item.terminal)[1] for item in items}
    for item in shipped:
        ident = identity_of(item.terminal)
        if ident in known or names.get(item.type_name, ident[1]) != ident[1]:
            continue
        items.append(item)
        known.add(ident)
    return TerminalRegistry(items)


class Describer:
    """Chooses the YAML of every identity on a rack (module docstring)."""

    def __init__(
        self,
        kept: Sequence[RegisteredTerminal],
        shipped: Sequence[RegisteredTerminal],
        catalog: Callable[[], EsiCatalog],
    ) -> None:
        self._kept = {identity_of(item.terminal): item for item in kept}
        self._shipped = {identity_of(item.terminal): item for item in shipped}
        self._all = [*kept, *shipped]
        self._open_catalog = catalog
        self._catalog: EsiCatalog | None = None
        self._from_esi: dict[tuple[str, int], TerminalType] = {}

    @property
    def catalog(self) -> EsiCatalog:
        if self._catalog is None:
            self._catalog = self._open_catalog()
        return self._catalog

    def describe(self, identity: Identity, slaves: list[TerminalPlan]) -> Described:
        """The YAML for `identity`; a `UserError` when nothing describes a
        slave with process data."""
        first = slaves[0]
        for found, origin in (
            (self._kept.get(identity), Origin.KEPT),
            (self._shipped.get(identity), Origin.SHIPPED),
        ):
            if found is not None:
                return self._copied(identity, found, origin, slaves)
        entry = self._esi_entry(identity)
        if entry is not None:
            exact = entry.revision == identity[2]
            nearest = (identity[0], identity[1], entry.revision)
            known = self._kept.get(nearest) or self._shipped.get(nearest)
            if not exact and known is not None:  # its comments and choices
                return self._copied(identity, known, Origin.NEAREST_YAML, slaves)
            terminal = self._generated(entry)
            return Described(
                identity=identity,
                type_name=entry.type_name,
                origin=Origin.GENERATED if exact else Origin.NEAREST,
                terminal=terminal,
                source=f"{entry.source}:{entry.line}",
                slaves=slaves,
            )
        other = self._other_revision(identity)
        if other is not None:
            return self._copied(identity, other, Origin.OTHER_YAML, slaves)
        with_data = [plan for plan in slaves if plan.points]
        if with_data:
            raise UserError(
                f"no ESI description and no terminal YAML of {type_label(first)} "
                f"(product code 0x{identity[1]:08x}, revision 0x{identity[2]:08x}; "
                f"{len(slaves)} on the rack, first {first.slave.name}), which has "
                "process data: give an --esi source that describes it",
                where="esi",
            )
        return Described(
            identity=identity,
            type_name=type_label(first),
            origin=Origin.NONE,
            terminal=None,
            slaves=slaves,
        )

    def _copied(
        self,
        identity: Identity,
        item: RegisteredTerminal,
        origin: Origin,
        slaves: list[TerminalPlan],
    ) -> Described:
        """A file's YAML as it is (a kept file keeps its name in DIR)."""
        kept = self._kept.get(identity_of(item.terminal)) is item
        return Described(
            identity=identity,
            type_name=item.type_name,
            origin=origin,
            terminal=item.terminal,
            file_name=item.path.name if kept else None,
            text=_read(item.path),
            source=str(item.path),
            slaves=slaves,
        )

    def by_type_name(self, type_name: str, revision: int | None) -> TerminalType:
        """The ESI's description of `type_name` at `revision` (else its
        nearest; None: the newest): for a chain file's type that no YAML
        describes, to play it (`UserError` when the ESI lacks the type)."""
        found = self.catalog.revisions(type_name)
        usable = [entry for entry in found if entry.parses]
        if not usable:
            return self._generated(self.catalog.find(type_name))
        wanted = usable[-1].revision if revision is None else revision
        return self._generated(
            min(usable, key=lambda e: revision_distance(e.revision, wanted))
        )

    def _generated(self, entry: CatalogEntry) -> TerminalType:
        key = (entry.source, entry.line)
        if key not in self._from_esi:
            device = self.catalog.load(entry.type_name, entry.revision)
            self._from_esi[key] = terminal_from_esi(device)
        return self._from_esi[key]

    def _esi_entry(self, identity: Identity) -> CatalogEntry | None:
        """The ESI's entry of exactly this revision, else its nearest usable
        revision of the product code; None when the ESI lacks the product."""
        vendor, product, revision = identity
        found = [
            entry
            for entry in self.catalog.entries
            if entry.product_code == product and entry.vendor_id == vendor
        ]
        exact = [
            entry for entry in found if entry.revision == revision and entry.parses
        ]
        if exact:
            return exact[0]
        usable = usable_revisions(found) or tuple(e for e in found if e.parses)
        if not usable:
            return None
        return min(usable, key=lambda e: revision_distance(e.revision, revision))

    def _other_revision(self, identity: Identity) -> RegisteredTerminal | None:
        _, product, revision = identity
        candidates = [
            item for item in self._all if item.terminal.identity.product_code == product
        ]
        if not candidates:
            return None
        return min(
            candidates,
            key=lambda item: revision_distance(
                item.terminal.identity.revision_number, revision
            ),
        )


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise UserError(f"cannot read: {error}", path=path) from None


def type_label(plan: TerminalPlan) -> str:
    """The slave's type as the YAML or TwinCAT names it (else its product code)."""
    slave = plan.slave
    return (
        plan.terminal_type or slave.type_name or f"0x{slave.identity.product_code:08x}"
    )


def group_by_identity(
    terminals: Iterable[TerminalPlan],
) -> dict[Identity, list[TerminalPlan]]:
    """The slaves of each identity, in bus order of their first."""
    found: dict[Identity, list[TerminalPlan]] = {}
    for plan in terminals:
        found.setdefault(slave_identity(plan), []).append(plan)
    return found


def file_names(described: Iterable[Described]) -> None:
    """Give every description with a YAML of its own a file name: a kept
    file keeps its name; a new one is `<TYPE>.yaml`, or `<TYPE>_r<REV>.yaml`
    when another revision of the type has that name already (the revision
    most terminals run gets the plain name)."""
    chosen = list(described)
    taken = {d.file_name for d in chosen if d.file_name is not None}
    served = {
        identity_of(d.terminal): d
        for d in chosen
        if d.terminal is not None and d.file_name is not None
    }
    for item in sorted(chosen, key=lambda d: -len(d.slaves)):
        if item.file_name is not None or item.terminal is None:
            continue
        same = served.get(identity_of(item.terminal))
        if same is not None:  # two revisions nearest to one in the ESI
            item.source = f"{item.source} (as {same.file_name})"
            continue
        served[identity_of(item.terminal)] = item
        name = terminal_file_name(item.type_name)
        if name in taken:
            revision = identity_of(item.terminal)[2]
            name = f"{item.type_name}_r{revision:08x}.yaml"
        item.file_name = name
        taken.add(name)
