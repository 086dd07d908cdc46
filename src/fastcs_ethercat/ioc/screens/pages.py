"""Screens as titled sections of rows, laid out and split into pages.

A `Screen` is what one display shows (a master's chain, a terminal, its CoE
objects); `render` places its sections as framed groups in columns and
starts a new page (`<file>_2.bob`, with Previous/Next buttons) before one
would hold more than `MAX_WIDGETS` widgets; a section too big for one page is
split across pages. Rows are the units the layout knows: a value (label,
widget, and the readback of a setpoint), a command, a device of the chain
(name, type, state coloured by its severity, a button to its page), a link.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum, auto
from typing import Final

from fastcs_ethercat.ioc.naming import RBV_SUFFIX
from fastcs_ethercat.ioc.screens import bob

MAX_WIDGETS: Final = 300
"""No display holds more widgets than this (Phoebus stays quick to open)."""
ROW_HEIGHT: Final = 26
GAP: Final = 6
LABEL_WIDTH: Final = 180
FIELD_WIDTH: Final = 150
COLUMN_WIDTH: Final = LABEL_WIDTH + 2 * FIELD_WIDTH + 4 * GAP + 10
GROUP_TITLE: Final = 24
MAX_COLUMN_HEIGHT: Final = 820
HEADER_HEIGHT: Final = 76
BUTTON_WIDTH: Final = 110
PLOT_ROWS: Final = 6
"""Rows a plot takes (the others take one)."""


class Show(Enum):
    """How a value is shown (and set, if it is a setpoint)."""

    TEXT = auto()
    STRING = auto()
    """A character array (an EPICS long string): shown and entered as text."""
    BOOL = auto()
    ENUM = auto()
    PLOT = auto()
    """An array (an oversampled channel): a plot of its samples."""


@dataclass(frozen=True)
class Value:
    """One attribute: what can be set (`write`: `pv` itself) and what is
    read (`read`: `pv`, or its `_RBV` when it is a setpoint too)."""

    label: str
    pv: str
    show: Show = Show.TEXT
    write: bool = False
    read: bool = True
    tooltip: str = ""
    units: str = ""
    limits: tuple[float, float] | None = None
    """The value's range, where it has one (a plot's Y axis)."""

    @property
    def widgets(self) -> int:
        return 1 + self.write + self.read

    @property
    def rows(self) -> int:
        return PLOT_ROWS if self.show is Show.PLOT and self.read else 1


@dataclass(frozen=True)
class Command:
    """A FastCS command: a button that writes 1 to its PV."""

    label: str
    pv: str
    widgets: int = 1


@dataclass(frozen=True)
class Device:
    """A coupler or terminal in a chain: its name, type, state and page."""

    label: str
    type_pv: str
    state_pv: str
    file: str
    tooltip: str = ""
    widgets: int = 5


@dataclass(frozen=True)
class Link:
    """A button to another display."""

    label: str
    file: str
    widgets: int = 1


Row = Value | Command | Device | Link


@dataclass(frozen=True)
class Section:
    title: str
    rows: tuple[Row, ...]

    @property
    def widgets(self) -> int:
        return 1 + sum(row.widgets for row in self.rows)


@dataclass(frozen=True)
class Screen:
    """One display (and its continuation pages): `file` without `.bob`."""

    file: str
    title: str
    sections: tuple[Section, ...]
    links: tuple[Link, ...] = field(default=())
    """Buttons under the title: up to the parent display, to related ones."""


def render(screen: Screen) -> list[tuple[str, ElementTree.ElementTree]]:
    """The display files of `screen`: (file name, XML), at most
    `MAX_WIDGETS` widgets each."""
    header = 1 + len(screen.links) + 2  # title, links, Previous/Next
    pages = list(_paginate(screen.sections, MAX_WIDGETS - header))
    files = [_page_file(screen.file, number) for number in range(len(pages))]
    rendered = []
    for number, sections in enumerate(pages):
        links = list(screen.links)
        if number > 0:
            links.append(Link("Previous page", files[number - 1]))
        if number + 1 < len(pages):
            links.append(Link("Next page", files[number + 1]))
        title = (
            screen.title
            if len(pages) == 1
            else f"{screen.title} ({number + 1}/{len(pages)})"
        )
        rendered.append((files[number], _display(title, links, sections)))
    return rendered


def page_file(stem: str) -> str:
    """The first display file of a screen."""
    return _page_file(stem, 0)


def _page_file(stem: str, number: int) -> str:
    return f"{stem}.bob" if number == 0 else f"{stem}_{number + 1}.bob"


def _paginate(sections: Sequence[Section], budget: int) -> Iterator[list[Section]]:
    """Sections in order, a new page before one would pass `budget` widgets;
    a section bigger than a page fills the current page first, then more."""
    page: list[Section] = []
    used = 0
    for section in sections:
        if used + section.widgets > budget and section.widgets <= budget:
            yield page
            page, used = [], 0
        for part in _split(section, budget - used, budget):
            if page and used + part.widgets > budget:
                yield page
                page, used = [], 0
            page.append(part)
            used += part.widgets
    if page or not sections:
        yield page


def _split(section: Section, first: int, budget: int) -> list[Section]:
    """`section`, or its rows in parts: the first fits `first` widgets (if
    any row does), the others `budget` each."""
    if section.widgets <= first:
        return [section]
    parts: list[list[Row]] = [[]]
    room, used = first, 1
    for row in section.rows:
        if used + row.widgets > room and (parts[-1] or room < budget):
            if parts[-1]:
                parts.append([])
            room, used = budget, 1
        parts[-1].append(row)
        used += row.widgets
    parts = [rows for rows in parts if rows]
    if len(parts) == 1:
        return [section]
    count = len(parts)
    return [
        replace(section, title=f"{section.title} ({k + 1}/{count})", rows=tuple(rows))
        for k, rows in enumerate(parts)
    ]


def _display(
    title: str, links: Sequence[Link], sections: Sequence[Section]
) -> ElementTree.ElementTree:
    widgets: list[ElementTree.Element] = []
    x = y = GAP
    right = bottom = 0
    for section in sections:
        height = GROUP_TITLE + _row_count(section.rows) * ROW_HEIGHT + 2 * GAP
        if y > GAP and y + height > MAX_COLUMN_HEIGHT:
            x, y = x + COLUMN_WIDTH + GAP, GAP
        box = bob.Box(x, HEADER_HEIGHT + y, COLUMN_WIDTH, height)
        widgets.append(bob.group(box, section.title, _rows(section.rows)))
        right, bottom = max(right, x + COLUMN_WIDTH), max(bottom, box.y + height)
        y += height + GAP
    width = max(right + GAP, COLUMN_WIDTH + 2 * GAP, len(links) * (BUTTON_WIDTH + GAP))
    head = [bob.label(bob.Box(GAP, GAP, width - 2 * GAP, 30), title, bold=True)]
    for index, link in enumerate(links):
        box = bob.Box(GAP + index * (BUTTON_WIDTH + GAP), 40, BUTTON_WIDTH, 28)
        head.append(bob.open_button(box, link.label, link.file))
    return bob.display(title, width, max(bottom, HEADER_HEIGHT) + GAP, head + widgets)


def _row_count(rows: Sequence[Row]) -> int:
    return sum(row.rows if isinstance(row, Value) else 1 for row in rows)


def _rows(rows: Sequence[Row]) -> Iterator[ElementTree.Element]:
    y = GAP
    for row in rows:
        yield from _row(row, y, ROW_HEIGHT - 4)
        y += (row.rows if isinstance(row, Value) else 1) * ROW_HEIGHT


def _row(row: Row, y: int, height: int) -> Iterator[ElementTree.Element]:
    first = bob.Box(GAP, y, LABEL_WIDTH, height)
    second = bob.Box(GAP * 2 + LABEL_WIDTH, y, FIELD_WIDTH, height)
    third = bob.Box(GAP * 3 + LABEL_WIDTH + FIELD_WIDTH, y, FIELD_WIDTH, height)
    match row:
        case Value():
            yield bob.label(first, row.label, row.tooltip)
            if row.write:
                yield _writer(second, row)
            if row.read and row.write:
                yield _reader(third, replace(row, pv=row.pv + RBV_SUFFIX))
            elif row.read:
                yield _reader(second, row)
        case Command():
            yield bob.write_button(first, row.label, row.pv)
        case Device():
            yield bob.label(bob.Box(GAP, y, 90, height), row.label, row.tooltip)
            type_box = bob.Box(GAP * 2 + 90, y, 130, height)
            yield bob.text_update(type_box, row.type_pv, string=True)
            yield bob.severity_led(
                bob.Box(GAP * 3 + 220, y, height, height), row.state_pv
            )
            state = bob.Box(GAP * 4 + 220 + height, y, 110, height)
            yield bob.text_update(state, row.state_pv)
            yield bob.open_button(
                bob.Box(GAP * 5 + 330 + height, y, 80, height), "Open", row.file
            )
        case Link():
            yield bob.open_button(first, row.label, row.file)


def _reader(box: bob.Box, value: Value) -> ElementTree.Element:
    if value.show is Show.BOOL:
        return bob.led(bob.Box(box.x, box.y, box.height, box.height), value.pv)
    if value.show is Show.PLOT:
        height = PLOT_ROWS * ROW_HEIGHT - 4
        plot = bob.Box(box.x, box.y, COLUMN_WIDTH - box.x - 2 * GAP, height)
        return bob.xy_plot(plot, value.pv, value.label, value.units, value.limits)
    return bob.text_update(box, value.pv, string=value.show is Show.STRING)


def _writer(box: bob.Box, value: Value) -> ElementTree.Element:
    if value.show is Show.BOOL:
        return bob.checkbox(box, value.pv)
    if value.show is Show.ENUM:
        return bob.combo(box, value.pv)
    return bob.text_entry(box, value.pv, string=value.show is Show.STRING)
