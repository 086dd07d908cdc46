"""The served tree as screens: the chain per master, a page per terminal.

- `index.bob`: the IOC's own PVs and a button per master;
- `ETH1.bob`: the master's PVs, then its couplers and terminals in bus order,
  each with its type, its AL state (an LED coloured by the PV's alarm
  severity, and the state itself) and a button to its page;
- `ETH1_RIO1_MOD5.bob`: the terminal's diagnostics and values of no channel,
  then one frame per channel; `..._CoE.bob`: one frame per CoE object.

Every PV the tree serves is on one of them (setpoints with their `_RBV`,
output waveforms included), and no display holds more than 300 widgets
(`pages.render` continues on `<file>_2.bob`). pvi, which FastCS uses for its
screens, lays out one signal per row under its label and has no widget
coloured by a PV's severity, so these are written here (`bob`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from fastcs.attributes import Attribute, AttrR, AttrW
from fastcs.controllers import BaseController
from fastcs.datatypes import Bool, Enum, String, Waveform

from fastcs_ethercat.ioc.attributes import CoeRef
from fastcs_ethercat.ioc.controllers.master import MasterController
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.ioc.controllers.terminal import TerminalController
from fastcs_ethercat.ioc.screens import bob
from fastcs_ethercat.ioc.screens.pages import (
    Command,
    Device,
    Link,
    Row,
    Screen,
    Section,
    Show,
    Value,
    page_file,
    render,
)

logger = logging.getLogger(__name__)

INDEX = "index"
COE_SUFFIX = "_CoE"

PvName = Callable[[list[str]], str]
"""A PV's name on the screens, from its FastCS path (`pva://` without CA)."""


def write_screens(root: RootController, directory: Path, *, ca: bool = True) -> int:
    """Write every display of `root` into `directory`; the number written."""
    directory.mkdir(parents=True, exist_ok=True)
    written = 0
    for screen in chain_screens(root, ca=ca):
        for name, tree in render(screen):
            bob.write_display(tree, directory / name)
            written += 1
    logger.info("%d screens written to %s", written, directory)
    return written


def chain_screens(root: RootController, *, ca: bool = True) -> list[Screen]:
    """Every screen of the tree, the index first."""

    def pv(path: list[str]) -> str:
        name = ":".join(path)
        return name if ca else f"pva://{name}"

    masters = root.masters
    index = Screen(
        INDEX,
        f"EtherCAT IOC {root.path[0]}",
        (
            Section("IOC", tuple(_rows(root, pv))),
            Section(
                "Masters",
                tuple(
                    Link(f"{m.path[-1]} {m.plan.name}", page_file(_stem(m)))
                    for m in masters
                ),
            ),
        ),
    )
    screens = [index]
    for master in masters:
        screens.append(_chain(master, pv))
        for terminal in _in_bus_order(master):
            screens += _terminal(terminal, master, pv)
    return screens


def _chain(master: MasterController, pv: PvName) -> Screen:
    """The master's PVs, then its couplers and terminals in bus order."""
    sections = [Section(f"Master {master.plan.name}", tuple(_rows(master, pv)))]
    segment = {t.plan.slave.name: t.path[-1] for t in master.terminals.values()}
    rows: list[Row] = []
    coupler: str | None = None
    for terminal in _in_bus_order(master):
        slave = terminal.plan.slave
        here = slave.name if slave.is_coupler else slave.coupler
        if rows and here != coupler:
            sections.append(_segment_section(coupler, segment, rows))
            rows = []
        coupler = here
        rows.append(_device(terminal, pv))
    if rows:
        sections.append(_segment_section(coupler, segment, rows))
    name = ":".join(master.path)
    return Screen(
        _stem(master),
        f"{name} {master.plan.name}",
        tuple(sections),
        (Link("IOC", page_file(INDEX)),),
    )


def _segment_section(
    coupler: str | None, segment: dict[str, str], rows: list[Row]
) -> Section:
    """The coupler's row and the terminals behind it, titled by the coupler
    (terminals before any coupler: "No coupler")."""
    if coupler is None:
        return Section("No coupler", tuple(rows))
    return Section(f"{segment.get(coupler, '')} {coupler}".strip(), tuple(rows))


def _terminal(
    terminal: TerminalController, master: MasterController, pv: PvName
) -> list[Screen]:
    """A terminal's page (diagnostics, channels) and its CoE page, if any."""
    stem, name = _stem(terminal), ":".join(terminal.path)
    kind = terminal.plan.terminal_type or "unknown type"
    channels: list[Section] = []
    objects: list[Section] = []
    for segment, part in terminal.parts.items():
        section = Section(
            f"{segment} {part.description or ''}".strip(), tuple(_rows(part, pv))
        )
        (objects if _is_coe(part) else channels).append(section)
    links = [Link("Chain", page_file(_stem(master)))]
    if objects:
        links.append(Link("CoE", page_file(stem + COE_SUFFIX)))
    own = Section(f"{terminal.plan.slave.name}: {kind}", tuple(_rows(terminal, pv)))
    screens = [
        Screen(
            stem, f"{name} {terminal.plan.slave.name}", (own, *channels), tuple(links)
        )
    ]
    if objects:
        screens.append(
            Screen(
                stem + COE_SUFFIX,
                f"{name} {terminal.plan.slave.name} CoE",
                tuple(objects),
                (Link("Terminal", page_file(stem)),),
            )
        )
    return screens


def _device(terminal: TerminalController, pv: PvName) -> Device:
    return Device(
        terminal.path[-1],
        pv(_pv_path(terminal.diag["Type"])),
        pv(_pv_path(terminal.diag["AlState"])),
        page_file(_stem(terminal)),
        terminal.plan.slave.name,
    )


def _rows(controller: BaseController, pv: PvName) -> Iterator[Row]:
    """A controller's own attributes and commands (not its sub-controllers')."""
    for name, attribute in controller.attributes.items():
        if isinstance(attribute, BaseController):
            continue
        units, limits = _units_and_limits(attribute.datatype)
        yield Value(
            name,
            pv([*controller.path, name]),
            _show(attribute),
            write=isinstance(attribute, AttrW),
            read=isinstance(attribute, AttrR),
            tooltip=_tooltip(attribute.description or "", units, limits),
            units=units,
            limits=limits,
        )
    for name in controller.command_methods:
        yield Command(name, pv([*controller.path, name]))


def _show(attribute: Attribute[Any, Any]) -> Show:
    match attribute.datatype:
        case Bool():
            return Show.BOOL
        case Enum():
            return Show.ENUM
        case String():
            return Show.STRING
        case Waveform():
            return Show.PLOT
        case _:
            return Show.TEXT


def _units_and_limits(datatype: Any) -> tuple[str, tuple[float, float] | None]:
    """A number's units and range (a waveform's: its samples' datatype has
    none here, so its plot scales itself)."""
    units = getattr(datatype, "units", None) or ""
    low, high = getattr(datatype, "min", None), getattr(datatype, "max", None)
    if low is None or high is None:
        return units, None
    return units, (float(low), float(high))


def _tooltip(description: str, units: str, limits: tuple[float, float] | None) -> str:
    """The description, then the units and range an operator enters within."""
    extra = f"{limits[0]:g} to {limits[1]:g}" if limits else ""
    extra = " ".join(part for part in (extra, units) if part)
    if not extra:
        return description
    return f"{description} ({extra})" if description else extra


def _is_coe(part: BaseController) -> bool:
    return any(
        attribute.has_io_ref() and isinstance(attribute.io_ref, CoeRef)
        for attribute in part.attributes.values()
    )


def _in_bus_order(master: MasterController) -> list[TerminalController]:
    return sorted(master.terminals.values(), key=lambda t: t.plan.slave.position)


def _stem(controller: BaseController) -> str:
    """A display's file name without `.bob`: the PV path below the prefix."""
    return "_".join(controller.path[1:])


def _pv_path(attribute: Attribute[Any, Any]) -> list[str]:
    return [*attribute.path, attribute.name]


__all__ = ["chain_screens", "write_screens"]
