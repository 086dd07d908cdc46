"""A `SystemPlan` -> the controllers below the root, with planned PV names.

Levels: root `<prefix>`, one `MasterController` per master, one controller
per coupler (a terminal controller that also holds the terminals behind it)
and one per terminal, with its channels and CoE objects below it. Every name
comes from `naming.plan_pv_names`, which is given every attribute of every
controller at once (`pv_requests`, one `PvRequest` per attribute made here
and nowhere else), so the names are deterministic for a plan and every
shortening is reported.

Built top-down: FastCS copies a controller's path into a sub-controller when
it is added, so a controller is attached before its own children are.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from fastcs.attributes import Attribute, AttrR, AttrRW, AttrW
from fastcs.controllers import BaseController, Controller

from fastcs_ethercat.ioc.attributes import CoeIO, CoeRef, PointRef, converts
from fastcs_ethercat.ioc.coe import SlaveCoe
from fastcs_ethercat.ioc.connection import Connection
from fastcs_ethercat.ioc.controllers.master import MASTER_LEAVES, MasterController
from fastcs_ethercat.ioc.controllers.terminal import (
    COE_REFRESH_LEAF,
    DIAGNOSTIC_LEAVES,
    GenericTerminalController,
    PvPlace,
    TerminalController,
    raw_leaf,
)
from fastcs_ethercat.ioc.datatypes import ca_record_type, type_label
from fastcs_ethercat.ioc.health import Health
from fastcs_ethercat.ioc.naming import (
    RBV_SUFFIX,
    Node,
    NodeKind,
    PvNames,
    PvRequest,
    coe_leaf,
    coe_request,
    point_request,
    twin_request,
)
from fastcs_ethercat.ioc.plan import (
    CoePoint,
    MasterPlan,
    SystemPlan,
    TerminalPlan,
)
from fastcs_ethercat.terminals.meaning import RAW_SUFFIX


@dataclass(frozen=True)
class PvEntry:
    """One served PV: its name, its type and where its value comes from."""

    name: str
    access: str  # "r", "w", "rw" (the `_RBV` twin is its own "r" entry)
    datatype: str
    source: str
    record: str = ""
    """The record type serving it on CA (`ai`, `bo`, `waveform`...; a
    command's: ""); not in `line()`, which keeps the list's four columns."""

    def line(self) -> str:
        return f"{self.name} {self.access} {self.datatype} {self.source}"


def slave_path(master: MasterPlan, terminal: TerminalPlan) -> tuple[Node, ...]:
    """The naming path of a slave: master, coupler (if any), the slave itself."""
    top = Node(NodeKind.MASTER, master.name)
    slave = terminal.slave
    if slave.is_coupler:
        return (top, Node(NodeKind.COUPLER, slave.name))
    if slave.coupler:
        return (
            top,
            Node(NodeKind.COUPLER, slave.coupler),
            Node(NodeKind.TERMINAL, slave.name),
        )
    return (top, Node(NodeKind.TERMINAL, slave.name))


def terminal_requests(
    path: tuple[Node, ...], terminal: TerminalPlan
) -> dict[str, PvRequest]:
    """Every attribute of a terminal controller by its leaf (a point's symbol,
    a scaled point's raw twin, a diagnostic, `Coe <attribute>`): values
    under their channel (a raw twin beside its value), CoE values under
    their object."""
    requests: dict[str, PvRequest] = {}
    for point in terminal.points:
        request = requests[point.symbol] = point_request(path, point)
        if converts(point):
            leaf = raw_leaf(point)
            requests[leaf] = twin_request(request, leaf, RAW_SUFFIX)
    requests |= {leaf: PvRequest(path, leaf) for leaf in DIAGNOSTIC_LEAVES}
    for coe in terminal.coe:
        leaf = coe_leaf(coe.attribute)
        requests[leaf] = coe_request(path, leaf, coe)
    if terminal.coe:
        requests[COE_REFRESH_LEAF] = PvRequest(path, COE_REFRESH_LEAF)
    return requests


def master_requests(master: MasterPlan) -> dict[str, PvRequest]:
    """Every attribute of a master controller by its leaf."""
    top = (Node(NodeKind.MASTER, master.name),)
    leaves = [*MASTER_LEAVES, *(point.symbol for point in master.master_points)]
    return {leaf: PvRequest(top, leaf) for leaf in leaves}


TerminalRequests = dict[int, dict[str, PvRequest]]
"""Each terminal's `terminal_requests`, by the id of its `TerminalPlan`."""


def requests_by_terminal(plan: SystemPlan) -> TerminalRequests:
    """Every terminal's requests, made once for a build: they name the PVs
    (`pv_requests`) and place the attributes (`build_masters`)."""
    return {
        id(terminal): terminal_requests(slave_path(master, terminal), terminal)
        for master in plan.masters
        for terminal in master.terminals
    }


def pv_requests(
    plan: SystemPlan,
    root_leaves: Sequence[str],
    by_terminal: TerminalRequests | None = None,
) -> list[PvRequest]:
    """Every attribute of the tree, for `plan_pv_names`."""
    if by_terminal is None:
        by_terminal = requests_by_terminal(plan)
    requests = [PvRequest((), leaf) for leaf in root_leaves]
    for master in plan.masters:
        requests += master_requests(master).values()
        for terminal in master.terminals:
            requests += by_terminal[id(terminal)].values()
    return requests


def build_masters(
    root: BaseController,
    plan: SystemPlan,
    names: PvNames,
    connection: Connection,
    health: Health,
    *,
    read_only: bool = False,
    by_terminal: TerminalRequests | None = None,
) -> list[MasterController]:
    """A controller per master of `plan` under `root`, with every terminal."""
    if by_terminal is None:
        by_terminal = requests_by_terminal(plan)
    masters: list[MasterController] = []
    for master in plan.masters:
        top = (Node(NodeKind.MASTER, master.name),)
        leaves = {
            leaf: names.leaves[request]
            for leaf, request in master_requests(master).items()
        }
        controller = MasterController(
            master, leaves, connection, health, read_only=read_only
        )
        root.add_sub_controller(names.controllers[top], controller)
        _add_terminals(controller, names, read_only, by_terminal)
        masters.append(controller)
    return masters


def _add_terminals(
    master_controller: MasterController,
    names: PvNames,
    read_only: bool,
    by_terminal: TerminalRequests,
) -> None:
    master = master_controller.plan
    by_path: dict[tuple[Node, ...], BaseController] = {
        (Node(NodeKind.MASTER, master.name),): master_controller
    }
    # couplers first (shorter paths), so a terminal's parent always exists
    ordered = sorted(
        master.terminals, key=lambda t: (len(slave_path(master, t)), t.slave.position)
    )
    for terminal in ordered:
        path = slave_path(master, terminal)
        parent = by_path.get(path[:-1])
        if parent is None:  # a coupler the master did not list: a bare level
            parent = _bare_coupler(names, by_path, path[:-1])
        kind = (
            TerminalController
            if terminal.terminal_type is not None
            else GenericTerminalController
        )
        controller = kind(
            terminal,
            _places(names, path, by_terminal[id(terminal)]),
            master_controller.point_io,
            _coe_io(master_controller.connection, master, terminal),
            read_only=read_only,
            health=master_controller.health,
        )
        parent.add_sub_controller(names.controllers[path], controller)
        by_path[path] = controller
        master_controller.add_terminal(controller)


def _coe_io(
    connection: Connection, master: MasterPlan, terminal: TerminalPlan
) -> CoeIO | None:
    """SDO access of one slave; refused while the target is away (or read-only)."""
    if not terminal.coe:
        return None
    sdo = SlaveCoe(connection.client, master.net_id, terminal.slave.address)

    async def read(coe: CoePoint) -> Any:
        connection.check_readable()
        return await sdo.read(coe)

    async def write(coe: CoePoint, value: Any) -> None:
        connection.check_writable("SDO write")
        await sdo.write(coe, value)

    return CoeIO(read, write)


def _bare_coupler(
    names: PvNames,
    by_path: dict[tuple[Node, ...], BaseController],
    path: tuple[Node, ...],
) -> BaseController:
    controller = Controller(description=path[-1].name)
    by_path[path[:-1]].add_sub_controller(names.controllers[path], controller)
    by_path[path] = controller
    return controller


def _places(
    names: PvNames, path: tuple[Node, ...], requests: dict[str, PvRequest]
) -> dict[str, PvPlace]:
    """Where each attribute of the controller at `path` sits below it."""
    return {leaf: names.below(request, len(path)) for leaf, request in requests.items()}


def pv_entries(root: BaseController) -> list[PvEntry]:
    """Every PV the tree serves (CA names), sorted by name."""
    return sorted(_walk(root), key=lambda entry: entry.name)


def pv_count(root: BaseController) -> int:
    """How many PVs `pv_entries` lists, without making and sorting them."""
    count = len(root.command_methods)
    for attr in root.attributes.values():
        if not isinstance(attr, BaseController):
            count += len(_pvs_of(attr))
    return count + sum(pv_count(sub) for sub in root.sub_controllers.values())


def _walk(controller: BaseController) -> Iterator[PvEntry]:
    path = ":".join(controller.path)
    for name, attr in controller.attributes.items():
        if isinstance(attr, BaseController):
            continue
        yield from _entries(f"{path}:{name}", attr)
    for name in controller.command_methods:
        yield PvEntry(f"{path}:{name}", "w", "Command", "command")
    for sub in controller.sub_controllers.values():
        yield from _walk(sub)


def _pvs_of(attr: Attribute) -> tuple[tuple[str, str], ...]:
    """(name suffix, access) of each PV an attribute gets."""
    if isinstance(attr, AttrRW):
        return (("", "rw"), (RBV_SUFFIX, "r"))
    if isinstance(attr, AttrR):
        return (("", "r"),)
    if isinstance(attr, AttrW):
        return (("", "w"),)
    return ()


def _entries(pv: str, attr: Attribute) -> Iterator[PvEntry]:
    datatype = type_label(attr.datatype)
    ref = attr.io_ref if attr.has_io_ref() else None
    if isinstance(ref, PointRef):
        source = ref.point.symbol
    elif isinstance(ref, CoeRef):
        coe = ref.coe
        source = f"CoE:{coe.index:04X}:{coe.subindex:02X}"
    else:
        source = "ioc"
    for suffix, access in _pvs_of(attr):
        record = ca_record_type(attr.datatype, output="w" in access)
        yield PvEntry(pv + suffix, access, datatype, source, record)
