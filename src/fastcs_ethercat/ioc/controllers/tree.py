"""A `SystemPlan` -> the whole controller tree, with planned PV names.

Levels: root `<prefix>`, one `MasterController` per master, one controller
per coupler (a terminal controller that also holds the terminals behind it)
and one per terminal. Every name comes from `naming.plan_pv_names`, which is
given every leaf of every controller at once, so the names are deterministic
for a plan and every shortening is reported.

Built top-down: FastCS copies a controller's path into a sub-controller when
it is added, so a controller is attached before its own children are.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from fastcs.attributes import Attribute, AttrR, AttrRW, AttrW
from fastcs.controllers import BaseController, Controller

from fastcs_ethercat.ioc.attributes import (
    CoeIO,
    CoeReader,
    CoeRef,
    CoeWriter,
    PointIO,
    PointRef,
    PointWriter,
)
from fastcs_ethercat.ioc.controllers.master import (
    MASTER_LEAVES,
    MasterController,
    MasterReader,
)
from fastcs_ethercat.ioc.controllers.root import ROOT_LEAVES, RootController
from fastcs_ethercat.ioc.controllers.terminal import (
    COE_REFRESH_LEAF,
    DIAGNOSTIC_LEAVES,
    GenericTerminalController,
    TerminalController,
    coe_leaf,
)
from fastcs_ethercat.ioc.health import Health
from fastcs_ethercat.ioc.naming import (
    RBV_SUFFIX,
    Node,
    NodeKind,
    PvNames,
    PvRequest,
    plan_pv_names,
)
from fastcs_ethercat.ioc.plan import MasterPlan, Point, SystemPlan, TerminalPlan

CoeAccess = Callable[[MasterPlan, TerminalPlan], tuple[CoeReader, CoeWriter] | None]
"""SDO reader and writer of one slave (None: no CoE access, e.g. in tests)."""
MasterReaderFactory = Callable[[MasterPlan], MasterReader | None]


@dataclass(frozen=True)
class PvEntry:
    """One served PV: its name, its type and where its value comes from."""

    name: str
    access: str  # "r", "w", "rw" (the `_RBV` twin is its own "r" entry)
    datatype: str
    source: str

    def line(self) -> str:
        return f"{self.name} {self.access} {self.datatype} {self.source}"


@dataclass
class Tree:
    """The built tree and what the app needs to feed it."""

    root: RootController
    names: PvNames
    masters: list[MasterController] = field(default_factory=list)
    sinks: dict[str, Any] = field(default_factory=dict)
    """Point key -> the controller whose `apply_change` posts it."""
    health: Health = field(default_factory=Health)

    def attribute(self, key: str) -> AttrR[Any, Any] | None:
        """The attribute serving point `key`, if any."""
        sink = self.sinks.get(key)
        return None if sink is None else sink.by_key.get(key)

    def terminals(self) -> list[TerminalController]:
        """Every terminal controller, master by master, in bus order."""
        return [t for master in self.masters for t in master.terminals.values()]

    def target_attributes(self) -> list[AttrR[Any, Any]]:
        """Every attribute whose value comes from the target (not the IOC)."""
        found: list[AttrR[Any, Any]] = []
        for master in self.masters:
            found += master.target_attributes()
            for terminal in master.terminals.values():
                found += terminal.target_attributes()
        return found

    def pvs(self) -> list[PvEntry]:
        """Every PV the tree serves (CA names), sorted by name."""
        return sorted(_walk(self.root), key=lambda entry: entry.name)

    def unserved(self) -> list[tuple[str, str]]:
        """(source, reason) of every point that got no PV."""
        found: list[tuple[str, str]] = []
        for master in self.masters:
            found += master.unserved
            for terminal in master.terminals.values():
                found += terminal.unserved
        return found


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


def terminal_leaves(terminal: TerminalPlan) -> list[str]:
    """Every leaf of a terminal controller: symbols, diagnostics, CoE."""
    leaves = [point.symbol for point in terminal.points]
    leaves += list(DIAGNOSTIC_LEAVES)
    if terminal.coe:
        leaves += [coe_leaf(coe.attribute) for coe in terminal.coe]
        leaves.append(COE_REFRESH_LEAF)
    return leaves


def pv_requests(plan: SystemPlan) -> list[PvRequest]:
    """Every attribute of the tree, for `plan_pv_names`."""
    requests = [PvRequest((), leaf) for leaf in ROOT_LEAVES]
    for master in plan.masters:
        top = (Node(NodeKind.MASTER, master.name),)
        requests += [PvRequest(top, leaf) for leaf in MASTER_LEAVES]
        requests += [PvRequest(top, point.symbol) for point in master.master_points]
        for terminal in master.terminals:
            path = slave_path(master, terminal)
            requests += [PvRequest(path, leaf) for leaf in terminal_leaves(terminal)]
    return requests


def build_tree(
    plan: SystemPlan,
    prefix: str,
    *,
    target: str,
    writer: PointWriter,
    aliases: Mapping[str, str] | None = None,
    coe_access: CoeAccess | None = None,
    master_reader: MasterReaderFactory | None = None,
    read_only: bool = False,
    health: Health | None = None,
) -> Tree:
    """The controller tree of `plan`, named under `prefix`."""
    names = plan_pv_names(prefix, pv_requests(plan), aliases)
    root_leaves = {leaf: names.leaves[PvRequest((), leaf)] for leaf in ROOT_LEAVES}
    root = RootController(prefix, plan, target, root_leaves)
    tree = Tree(root, names, health=health or Health())
    point_io = PointIO(writer)
    for master in plan.masters:
        top = (Node(NodeKind.MASTER, master.name),)
        leaves = _leaves(names, top, [*MASTER_LEAVES, *_symbols(master.master_points)])
        reader = master_reader(master) if master_reader is not None else None
        controller = MasterController(
            master, leaves, point_io, reader, read_only=read_only, health=tree.health
        )
        root.add_sub_controller(names.controllers[top], controller)
        tree.masters.append(controller)
        for point in master.master_points:
            tree.sinks[point.key] = controller
        _add_terminals(tree, master, controller, point_io, coe_access, read_only)
    root.pv_count = sum(1 for _ in _walk(root))
    root.unserved = len(tree.unserved())
    return tree


def _add_terminals(
    tree: Tree,
    master: MasterPlan,
    master_controller: MasterController,
    point_io: PointIO,
    coe_access: CoeAccess | None,
    read_only: bool,
) -> None:
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
            parent = _bare_coupler(tree, by_path, path[:-1])
        access = coe_access(master, terminal) if coe_access is not None else None
        coe_io = CoeIO(*access) if access is not None else None
        kind = (
            TerminalController
            if terminal.terminal_type is not None
            else GenericTerminalController
        )
        controller = kind(
            terminal,
            _leaves(tree.names, path, terminal_leaves(terminal)),
            point_io,
            coe_io,
            read_only=read_only,
            health=tree.health,
        )
        parent.add_sub_controller(tree.names.controllers[path], controller)
        by_path[path] = controller
        master_controller.terminals[terminal.slave.address] = controller
        for point in terminal.points:
            tree.sinks[point.key] = controller


def _bare_coupler(
    tree: Tree, by_path: dict[tuple[Node, ...], BaseController], path: tuple[Node, ...]
) -> BaseController:
    controller = Controller(description=path[-1].name)
    by_path[path[:-1]].add_sub_controller(tree.names.controllers[path], controller)
    by_path[path] = controller
    return controller


def _symbols(points: list[Point]) -> list[str]:
    return [point.symbol for point in points]


def _leaves(
    names: PvNames, path: tuple[Node, ...], leaves: list[str]
) -> dict[str, str]:
    return {leaf: names.leaves[PvRequest(path, leaf)] for leaf in leaves}


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


def _entries(pv: str, attr: Attribute) -> Iterator[PvEntry]:
    datatype = type(attr.datatype).__name__
    ref = attr.io_ref if attr.has_io_ref() else None
    if isinstance(ref, PointRef):
        source = ref.point.symbol
    elif isinstance(ref, CoeRef):
        coe = ref.coe
        source = f"CoE:{coe.index:04X}:{coe.subindex:02X}"
    else:
        source = "ioc"
    if isinstance(attr, AttrRW):
        yield PvEntry(pv, "rw", datatype, source)
        yield PvEntry(pv + RBV_SUFFIX, "r", datatype, source)
    elif isinstance(attr, AttrR):
        yield PvEntry(pv, "r", datatype, source)
    elif isinstance(attr, AttrW):
        yield PvEntry(pv, "w", datatype, source)
