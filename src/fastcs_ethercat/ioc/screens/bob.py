"""Phoebus display files (`.bob`): the few widgets the IOC's screens use.

The format is Phoebus' own XML (`<display version="2.0.0">` holding
`<widget type="..." version="...">` elements, each property a child element);
the widget types and versions are those Phoebus itself writes (`WIDGET_TYPES`),
the rule syntax is that of its `RulesWidgetProperty` (`pvSev0` is the
severity of the rule's first PV: 0 no alarm, 1 minor, 2 major, 3 invalid,
4 undefined). Only geometry and PVs are given; every other property keeps
Phoebus' default (alarm-sensitive borders included).
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

WIDGET_TYPES: Final = {
    "action_button": "3.0.0",
    "checkbox": "2.0.0",
    "combo": "2.0.0",
    "group": "3.0.0",
    "label": "2.0.0",
    "led": "2.0.0",
    "textentry": "3.0.0",
    "textupdate": "2.0.0",
    "xyplot": "3.0.0",
}
"""Every widget type written here, with the version Phoebus writes for it."""
DISPLAY_VERSION: Final = "2.0.0"
STRING_FORMAT: Final = "6"
"""`FormatOption.STRING` of a text widget's `format`: a character array (an
EPICS long string) shown as its text, not as the numbers of its bytes."""


@dataclass(frozen=True)
class Color:
    name: str
    red: int
    green: int
    blue: int


SEVERITY_COLORS: Final = (
    Color("OK", 0, 255, 0),
    Color("MINOR", 255, 128, 0),
    Color("MAJOR", 255, 0, 0),
)
"""Phoebus' named alarm colours by `pvSev0`: no alarm, minor, major."""
INVALID_COLOR: Final = Color("INVALID", 255, 0, 255)
"""Invalid or undefined (disconnected): what the rules fall back to."""


@dataclass(frozen=True)
class Box:
    """Where a widget goes, relative to its parent (display or group)."""

    x: int
    y: int
    width: int
    height: int


def label(
    box: Box, text: str, tooltip: str = "", bold: bool = False
) -> ElementTree.Element:
    widget = _widget("label", box, text)
    _add(widget, "text", text)
    if tooltip:
        _add(widget, "tooltip", tooltip)
    if bold:
        font = _add(widget, "font")
        ElementTree.SubElement(
            font, "font", family="Liberation Sans", style="BOLD", size="16.0"
        )
    return widget


def text_update(box: Box, pv: str, *, string: bool = False) -> ElementTree.Element:
    """The value of `pv` (with the PV's units); `string`: shown as text."""
    return _text_widget("textupdate", box, pv, string)


def text_entry(box: Box, pv: str, *, string: bool = False) -> ElementTree.Element:
    return _text_widget("textentry", box, pv, string)


def xy_plot(
    box: Box,
    pv: str,
    title: str,
    units: str = "",
    limits: tuple[float, float] | None = None,
) -> ElementTree.Element:
    """The samples of an array PV against their index; the Y axis titled
    with its units and fixed to `limits` (the value's range) if given."""
    widget = _widget("xyplot", box, pv)
    _add(widget, "title", title)
    _add(widget, "show_legend", "false")
    x_axis = _add(widget, "x_axis")
    _add(x_axis, "title", "Sample")
    _add(x_axis, "autoscale", "true")
    y_axis = _add(_add(widget, "y_axes"), "y_axis")
    _add(y_axis, "title", units or "Value")
    _add(y_axis, "autoscale", "false" if limits else "true")
    if limits:
        _add(y_axis, "minimum", f"{limits[0]:g}")
        _add(y_axis, "maximum", f"{limits[1]:g}")
    trace = _add(_add(widget, "traces"), "trace")
    _add(trace, "name", title)
    _add(trace, "x_pv", "")
    _add(trace, "y_pv", pv)
    _add(trace, "y_axis", "0")
    return widget


def combo(box: Box, pv: str) -> ElementTree.Element:
    """A choice of the PV's own states (Phoebus reads them from the PV)."""
    return _pv_widget("combo", box, pv)


def checkbox(box: Box, pv: str) -> ElementTree.Element:
    widget = _pv_widget("checkbox", box, pv)
    _add(widget, "label", "")
    return widget


def led(box: Box, pv: str) -> ElementTree.Element:
    return _pv_widget("led", box, pv)


def severity_led(box: Box, pv: str) -> ElementTree.Element:
    """An LED coloured by the alarm severity of `pv`, whatever its value."""
    widget = led(box, pv)
    for prop in ("off_color", "on_color"):
        _color(_add(widget, prop), INVALID_COLOR)
    rules = _add(widget, "rules")
    for prop in ("off_color", "on_color"):
        rule = ElementTree.SubElement(
            rules, "rule", name=f"Severity {prop}", prop_id=prop, out_exp="false"
        )
        for severity, color in enumerate(SEVERITY_COLORS):
            expression = ElementTree.SubElement(
                rule, "exp", bool_exp=f"pvSev0=={severity}"
            )
            _color(_add(expression, "value"), color)
        _add(rule, "pv_name", pv)
    return widget


def write_button(box: Box, text: str, pv: str, value: str = "1") -> ElementTree.Element:
    """A button that writes `value` to `pv` (a FastCS command)."""
    widget = _widget("action_button", box, text)
    action = ElementTree.SubElement(_add(widget, "actions"), "action", type="write_pv")
    _add(action, "description", text)
    _add(action, "pv_name", pv)
    _add(action, "value", value)
    _add(widget, "pv_name", pv)
    _add(widget, "text", text)
    return widget


def open_button(box: Box, text: str, file: str) -> ElementTree.Element:
    """A button that opens another display of the same folder in place."""
    widget = _widget("action_button", box, text)
    actions = _add(widget, "actions")
    action = ElementTree.SubElement(actions, "action", type="open_display")
    _add(action, "description", text)
    _add(action, "file", file)
    _add(action, "target", "replace")
    _add(widget, "text", text)
    return widget


def group(
    box: Box, title: str, children: Iterable[ElementTree.Element]
) -> ElementTree.Element:
    """A titled frame; its children's boxes are relative to its inside."""
    widget = _widget("group", box, title)
    widget.extend(children)
    return widget


def display(
    title: str, width: int, height: int, widgets: Sequence[ElementTree.Element]
) -> ElementTree.ElementTree:
    root = ElementTree.Element("display", version=DISPLAY_VERSION)
    _add(root, "name", title)
    _add(root, "width", str(width))
    _add(root, "height", str(height))
    root.extend(widgets)
    ElementTree.indent(root)
    return ElementTree.ElementTree(root)


def write_display(tree: ElementTree.ElementTree, path: Path) -> None:
    tree.write(path, encoding="UTF-8", xml_declaration=True)


def _widget(kind: str, box: Box, name: str) -> ElementTree.Element:
    widget = ElementTree.Element("widget", type=kind, version=WIDGET_TYPES[kind])
    _add(widget, "name", name)
    for key in ("x", "y", "width", "height"):
        _add(widget, key, str(getattr(box, key)))
    return widget


def _text_widget(kind: str, box: Box, pv: str, string: bool) -> ElementTree.Element:
    widget = _pv_widget(kind, box, pv)
    if string:
        _add(widget, "format", STRING_FORMAT)
    return widget


def _pv_widget(kind: str, box: Box, pv: str) -> ElementTree.Element:
    widget = _widget(kind, box, pv)
    _add(widget, "pv_name", pv)
    return widget


def _add(
    parent: ElementTree.Element, tag: str, text: str | None = None
) -> ElementTree.Element:
    child = ElementTree.SubElement(parent, tag)
    if text is not None:
        child.text = text
    return child


def _color(parent: ElementTree.Element, color: Color) -> None:
    ElementTree.SubElement(
        parent,
        "color",
        name=color.name,
        red=str(color.red),
        green=str(color.green),
        blue=str(color.blue),
    )
