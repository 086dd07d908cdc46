"""What a rack runs, as its chain file says it, and what changed between two.

A chain (the simulator's format, `chain dump`'s and `init`'s `chain.yaml`)
lists every slave by master in bus order with its TwinCAT name, type,
revision, PDO group and oversampling factor. `rack_slaves` reads those as
`RackSlave`s; `rack_changes` compares an earlier chain with the rack now:
slaves are matched by master and TwinCAT name (TwinCAT keeps a terminal's
name when others are added or removed), and a slave gone from a position
where another type now sits is a swap.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the chain format is read only where a chain is
    from fastcs_ethercat.chain.file import Chain


@dataclass(frozen=True, slots=True)
class RackSlave:
    """One slave of the rack: where it is and what it runs."""

    master: str
    position: int
    name: str
    type_name: str
    revision: int | None
    pdo_group: str | None
    oversampling: int | None

    @property
    def key(self) -> tuple[str, str]:
        return (self.master, self.name)

    @property
    def identity(self) -> str:
        """`EL3104 revision 0x00110000` (the type alone when not known)."""
        if self.revision is None:
            return self.type_name
        return f"{self.type_name} revision 0x{self.revision:08x}"


def rack_slaves(chain: Chain) -> list[RackSlave]:
    """Every slave of `chain`, masters in order, each in bus order (names as
    TwinCAT and the simulator default them where the chain gives none)."""
    slaves: list[RackSlave] = []
    number = 1
    for index, master in enumerate(chain.masters):
        master_name = master.name or f"Device {index + 1} (EtherCAT)"
        for position, spec in enumerate(master.slaves):
            slaves.append(
                RackSlave(
                    master=master_name,
                    position=position,
                    name=spec.name or f"Term {number} ({spec.type})",
                    type_name=spec.type,
                    revision=spec.revision,
                    pdo_group=spec.pdo_group,
                    oversampling=spec.oversampling,
                )
            )
            number += 1
    return slaves


class ChangeKind(StrEnum):
    """What happened to one slave between two chains."""

    ADDED = "added"
    REMOVED = "removed"
    SWAPPED = "swapped"
    REVISION = "other revision"
    PDO_GROUP = "other PDO group"
    OVERSAMPLING = "other oversampling"


@dataclass(frozen=True, slots=True)
class RackChange:
    """One change on the rack, and the line that tells it."""

    kind: ChangeKind
    before: RackSlave | None
    after: RackSlave | None

    @property
    def slave(self) -> RackSlave:
        """The slave as it is now (as it was, when removed)."""
        found = self.after if self.after is not None else self.before
        assert found is not None
        return found

    def line(self) -> str:
        before, after = self.before, self.after
        match self.kind:
            case ChangeKind.ADDED:
                assert after is not None
                return f"added: {after.name} ({after.identity}) on {after.master}"
            case ChangeKind.REMOVED:
                assert before is not None
                return (
                    f"removed: {before.name} ({before.identity}) from {before.master}"
                )
        assert before is not None and after is not None
        match self.kind:
            case ChangeKind.SWAPPED:
                return (
                    f"swapped: {before.name} ({before.identity}) -> "
                    f"{after.name} ({after.identity}) on {after.master}"
                )
            case ChangeKind.REVISION:
                return (
                    f"other revision: {after.name}: {before.identity} -> "
                    f"{after.identity}"
                )
            case ChangeKind.PDO_GROUP:
                return (
                    f"other PDO group: {after.name}: {before.pdo_group!r} -> "
                    f"{after.pdo_group!r}"
                )
        return (
            f"other oversampling: {after.name}: {before.oversampling} -> "
            f"{after.oversampling}"
        )


def rack_changes(before: list[RackSlave], after: list[RackSlave]) -> list[RackChange]:
    """What changed from `before` to `after`, in the order of `after` (then
    what was removed, in the order of `before`)."""
    old = {slave.key: slave for slave in before}
    new = {slave.key: slave for slave in after}
    changes: list[RackChange] = []
    gone = [slave for slave in before if slave.key not in new]
    swapped: set[tuple[str, str]] = set()
    for slave in after:
        earlier = old.get(slave.key)
        if earlier is None:
            partner = _swapped_out(slave, gone, swapped)
            kind = ChangeKind.ADDED if partner is None else ChangeKind.SWAPPED
            changes.append(RackChange(kind, partner, slave))
            continue
        changes.extend(_same_slave(earlier, slave))
    changes += [
        RackChange(ChangeKind.REMOVED, slave, None)
        for slave in gone
        if slave.key not in swapped
    ]
    return changes


def _swapped_out(
    slave: RackSlave, gone: list[RackSlave], taken: set[tuple[str, str]]
) -> RackSlave | None:
    """The removed slave whose place `slave` (a new one) took: same master,
    same position, another type."""
    for candidate in gone:
        if (
            candidate.key not in taken
            and candidate.master == slave.master
            and candidate.position == slave.position
            and candidate.type_name != slave.type_name
        ):
            taken.add(candidate.key)
            return candidate
    return None


def _same_slave(before: RackSlave, after: RackSlave) -> list[RackChange]:
    if before.type_name != after.type_name:
        return [RackChange(ChangeKind.SWAPPED, before, after)]
    found: list[RackChange] = []
    if before.revision != after.revision:
        found.append(RackChange(ChangeKind.REVISION, before, after))
    if before.pdo_group != after.pdo_group:
        found.append(RackChange(ChangeKind.PDO_GROUP, before, after))
    if before.oversampling != after.oversampling:
        found.append(RackChange(ChangeKind.OVERSAMPLING, before, after))
    return found
