"""Symbol nodes expanded per channel: the I/O symbols as TwinCAT lists them.

The YAML stores one node per PDO template; the simulator needs one symbol
per channel (to build the symbol and data-type tables) and the IOC needs the
same to match the live symbol table. Both get it from `expanded_symbols`, so
the `{channel}` and oversampling rules live in one place.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from fastcs_ethercat.terminals.meaning import (
    Scaling,
    member_scaling,
    member_severity,
)
from fastcs_ethercat.terminals.model import (
    Direction,
    SeverityName,
    SymbolAccess,
    TerminalType,
)
from fastcs_ethercat.terminals.names import expand


@dataclass(frozen=True, slots=True)
class ExpandedMember:
    """One entry of one concrete symbol."""

    name: str
    """Entry name, channel filled in (`Status__Underrange`, `Ch1 Value`)."""
    fastcs_name: str
    type_name: str
    bit_offset: int
    """Within the symbol (within one sample for oversampled symbols)."""
    bit_size: int
    coe_index: int | None
    coe_subindex: int | None
    comment: str | None
    scaling: Scaling | None = None
    """What the value is served as (`terminals.meaning`); None: raw."""
    severity: SeverityName = "none"
    """Alarm severity while the bit or field is set."""

    @property
    def path(self) -> tuple[str, ...]:
        """The ESI name split at `__`: ("Status", "Underrange")."""
        return tuple(self.name.split("__"))


@dataclass(frozen=True, slots=True)
class ExpandedSymbol:
    """One I/O symbol of a terminal: `<terminal name>.<name>` in TwinCAT."""

    name: str
    fastcs_name: str
    type_name: str
    channel: int | None
    pdo_index: int | None
    direction: Direction
    access: SymbolAccess
    samples: int
    """Copies of the members (the oversampling factor; 1 otherwise)."""
    sample_bit_size: int
    members: tuple[ExpandedMember, ...]
    selected: bool
    node_index: int

    @property
    def entry_name(self) -> str:
        """The ESI entry a point of the whole symbol reads: its one member
        (`Value` of `AI Compact Channel 1`); "" when it has several."""
        return ".".join(self.members[0].path) if len(self.members) == 1 else ""

    @property
    def bit_size(self) -> int:
        """Whole size in the process image."""
        return self.sample_bit_size * self.samples

    @property
    def byte_size(self) -> int:
        return (self.bit_size + 7) // 8


def expanded_symbols(
    terminal: TerminalType,
    *,
    selected_only: bool = False,
    nodes: Sequence[int] | None = None,
) -> list[ExpandedSymbol]:
    """Every symbol per channel, in node order (only selected ones if asked);
    with `nodes`, those symbol nodes' only, in that order (a terminal with
    many PDO groups serves a few of its nodes: the rest are not worth their
    members)."""
    result: list[ExpandedSymbol] = []
    indices = range(len(terminal.symbol_nodes)) if nodes is None else nodes
    for node_index in indices:
        node = terminal.symbol_nodes[node_index]
        if selected_only and not node.selected:
            continue
        samples = terminal.sample_count(node)
        for position, channel in node.channel_positions():
            members = []
            for member in node.members:
                index, subindex = (
                    member.address(position) if member.coe else (None, None)
                )
                members.append(
                    ExpandedMember(
                        name=expand(member.name, channel),
                        fastcs_name=expand(member.fastcs_name, channel),
                        type_name=member.type_name,
                        bit_offset=member.bit_offset,
                        bit_size=member.bit_size,
                        coe_index=index,
                        coe_subindex=subindex,
                        comment=member.comment,
                        scaling=member_scaling(member),
                        severity=member_severity(member, node.direction),
                    )
                )
            result.append(
                ExpandedSymbol(
                    name=expand(node.name_template, channel),
                    fastcs_name=expand(node.fastcs_name, channel),
                    type_name=expand(node.type_name, channel),
                    channel=channel,
                    pdo_index=node.pdo_indices[position] if node.pdo_indices else None,
                    direction=node.direction,
                    access=node.access,
                    samples=samples,
                    sample_bit_size=node.bit_size,
                    members=tuple(members),
                    selected=node.selected,
                    node_index=node_index,
                )
            )
    return result
