"""The PV names a terminal's selected symbols and CoE objects will get.

Named by the IOC's own planner (`ioc.naming.plan_pv_names`), so the preview
shortens as the IOC will. The engineer types the PV prefix of one terminal
of the type (`BL45P-MO-IOC-01:ETH1:RIO1:MOD5`); the three trailing segments
say which master, coupler and terminal position to name. The IOC budgets
each level by the longest of its whole chain: type a terminal number of as
many digits as the chain's longest (`MOD105` on a rack of over 99).
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
    coe_leaf,
    coe_request,
    plan_pv_names,
    symbol_request,
    twin_request,
)
from fastcs_ethercat.ioc.resolve import coe_points
from fastcs_ethercat.terminals.meaning import RAW_SUFFIX, has_raw_twin
from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.symbols import expanded_symbols

TERMINAL_PREFIX = re.compile(r"^(?P<ioc>.+):ETH(?P<m>\d+):RIO(?P<c>\d+):MOD(?P<t>\d+)$")
EXAMPLE_PREFIX = "BL45P-MO-IOC-01:ETH1:RIO1:MOD5"


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
    request: PvRequest
    source: str
    node: int | None = None
    channel: int | None = None
    member: str | None = None


def _leaves(
    terminal: TerminalType, terminal_name: str, path: tuple[Node, ...]
) -> list[_Leaf]:
    """One leaf per PV of the selected symbols and CoE objects, requested as
    the IOC requests its points (`ioc.controllers.tree.terminal_requests`)."""
    leaves: list[_Leaf] = []
    for symbol in expanded_symbols(terminal, selected_only=True):
        writable = symbol.direction == "output"
        name = f"{terminal_name}.{symbol.name}"
        where = {"node": symbol.node_index, "channel": symbol.channel}
        if symbol.type_name.endswith("_TYPE") and symbol.members:
            for member in symbol.members:
                entry_name = ".".join(member.path)
                leaf = f"{name}.{entry_name}"
                request = symbol_request(
                    path,
                    leaf,
                    entry_name=entry_name,
                    channel=symbol.channel,
                    writable=writable,
                )
                leaves.append(_Leaf(request, leaf, member=member.name, **where))
                if has_raw_twin(member.scaling):
                    leaves.append(_raw_twin(request, leaf, member.name, **where))
        else:
            request = symbol_request(
                path,
                name,
                entry_name=symbol.entry_name,
                channel=symbol.channel,
                writable=writable,
            )
            leaves.append(_Leaf(request, name, **where))
            if len(symbol.members) == 1 and has_raw_twin(symbol.members[0].scaling):
                leaves.append(_raw_twin(request, name, None, **where))
    for coe in coe_points(terminal):
        request = coe_request(path, coe_leaf(coe.attribute), coe)
        sub = f":{coe.subindex:02x}" if coe.subindex else ""
        source = f"CoE 0x{coe.index:04x}{sub}"
        leaves.append(_Leaf(request, source))
    return leaves


def _raw_twin(
    value: PvRequest,
    source: str,
    member: str | None,
    node: int | None,
    channel: int | None,
) -> _Leaf:
    """The leaf of a scaled value's raw count, beside it (as the IOC serves it)."""
    leaf = source + RAW_SUFFIX
    return _Leaf(twin_request(value, leaf, RAW_SUFFIX), source, node, channel, member)


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
    leaves = _leaves(terminal, terminal_name, path)
    names = plan_pv_names(found["ioc"], [item.request for item in leaves])
    why = {s.node: s.reason for s in names.shortened}
    return [
        PvPreview(
            source=item.source,
            pv=names.pv(item.request),
            writable=item.request.writable,
            node=item.node,
            channel=item.channel,
            member=item.member,
            shortened=why.get(item.request),
        )
        for item in leaves
    ]


__all__ = ["EXAMPLE_PREFIX", "MAX_PV_LENGTH", "PvPreview", "preview_pvs"]
