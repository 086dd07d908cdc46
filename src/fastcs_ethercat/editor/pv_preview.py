"""The PV names a terminal's selected symbols and CoE objects will get.

Named by the IOC's own planner (`ioc.naming.plan_pv_names`), so the preview
shortens exactly as the IOC will. The engineer types the PV prefix of one
terminal of the type (`BL45P-MO-IOC-01:ETH1:RIO1:MOD5`); the three trailing
segments say which master, coupler and terminal position to name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.naming import (
    MAX_PV_LENGTH,
    RBV_SUFFIX,
    Node,
    NodeKind,
    PvRequest,
    plan_pv_names,
)
from fastcs_ethercat.terminals.meaning import RAW_SUFFIX, has_raw_twin
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.symbols import expanded_symbols

TERMINAL_PREFIX = re.compile(r"^(?P<ioc>.+):ETH(?P<m>\d+):RIO(?P<c>\d+):MOD(?P<t>\d+)$")
EXAMPLE_PREFIX = "BL45P-MO-IOC-01:ETH1:RIO1:MOD5"
COE_LEAF_PREFIX = "Coe "
"""The IOC's CoE leaves are `Coe <attribute>` (ioc.controllers.terminal)."""


@dataclass(frozen=True)
class PvPreview:
    """One PV a selection makes."""

    source: str
    """What it serves: a TwinCAT symbol path or a CoE address."""
    pv: str
    writable: bool
    node: int | None
    """Position of its symbol node (None for CoE)."""
    channel: int | None = None
    member: str | None = None
    """The member's ESI name (`Status__Underrange`), None for a whole symbol."""
    shortened: str | None = None
    """Why the readable name did not fit, when it did not."""

    @property
    def longest(self) -> int:
        """Characters of the longest name it makes (with `_RBV`)."""
        return len(self.pv) + (len(RBV_SUFFIX) if self.writable else 0)


@dataclass(frozen=True)
class _Leaf:
    leaf: str
    source: str
    writable: bool
    node: int | None = None
    channel: int | None = None
    member: str | None = None


def _leaves(terminal: TerminalType, terminal_name: str) -> list[_Leaf]:
    """One leaf per PV of the selected symbols and CoE objects."""
    leaves: list[_Leaf] = []
    for symbol in expanded_symbols(terminal, selected_only=True):
        writable = symbol.direction == "output"
        name = f"{terminal_name}.{symbol.name}"
        where = {"node": symbol.node_index, "channel": symbol.channel}
        if symbol.type_name.endswith("_TYPE") and symbol.members:
            for member in symbol.members:
                path = f"{name}.{'.'.join(member.path)}"
                leaves.append(_Leaf(path, path, writable, member=member.name, **where))
                if has_raw_twin(member.scaling):
                    raw = path + RAW_SUFFIX
                    leaves.append(_Leaf(raw, path, False, member=member.name, **where))
        else:
            leaves.append(_Leaf(name, name, writable, **where))
            if len(symbol.members) == 1 and has_raw_twin(symbol.members[0].scaling):
                leaves.append(_Leaf(name + RAW_SUFFIX, name, False, **where))
    for obj in terminal.coe_objects:
        if not obj.selected:
            continue
        if not obj.sub_items:
            leaves.append(
                _Leaf(
                    COE_LEAF_PREFIX + obj.fastcs_name,
                    f"CoE 0x{obj.index:04x}",
                    obj.access in ("rw", "wo"),
                )
            )
        for sub in obj.sub_items:
            if sub.selected:
                leaves.append(
                    _Leaf(
                        f"{COE_LEAF_PREFIX}{obj.fastcs_name}_{sub.fastcs_name}",
                        f"CoE 0x{obj.index:04x}:{sub.subindex:02x}",
                        (sub.access or obj.access) in ("rw", "wo"),
                    )
                )
    return leaves


def preview_pvs(terminal: TerminalType, type_name: str, prefix: str) -> list[PvPreview]:
    """Every PV the selection makes under the terminal PV prefix `prefix`.

    Raises `UserError` (one line, for the prefix field) when the prefix is
    not a terminal's PV prefix or its IOC part cannot be a PV prefix."""
    found = TERMINAL_PREFIX.match(prefix.strip())
    if found is None:
        raise UserError(
            f"type a terminal's PV prefix, like {EXAMPLE_PREFIX}", where="prefix"
        )
    terminal_name = f"Term {int(found['t'])} ({type_name})"
    path = (
        Node(NodeKind.MASTER, f"Device {int(found['m'])} (EtherCAT)"),
        Node(NodeKind.COUPLER, f"Term {int(found['c'])} (EK1100)"),
        Node(NodeKind.TERMINAL, terminal_name),
    )
    leaves = _leaves(terminal, terminal_name)
    names = plan_pv_names(found["ioc"], [PvRequest(path, item.leaf) for item in leaves])
    why = {s.source.rsplit("^", 1)[-1]: s.reason for s in names.shortened}
    relative = len(terminal_name) + 1
    return [
        PvPreview(
            source=item.source,
            pv=names.pv(PvRequest(path, item.leaf)),
            writable=item.writable,
            node=item.node,
            channel=item.channel,
            member=item.member,
            shortened=why.get(
                item.leaf[relative:]
                if item.leaf.startswith(terminal_name)
                else item.leaf
            ),
        )
        for item in leaves
    ]


__all__ = ["EXAMPLE_PREFIX", "MAX_PV_LENGTH", "PvPreview", "preview_pvs"]
