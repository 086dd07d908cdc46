"""Screens as a chain (issue 14 item 6): the demo chain's `.bob` files parse,
hold only Phoebus' own widgets, show every served PV, and no display holds
more than 300 widgets, with the default selections and with every CoE
object selected. The tree is built in-process (`tree_support`)."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest

from fastcs_ethercat.bench.chains import terminals_with_coe
from fastcs_ethercat.ioc.controllers.root import RootController
from fastcs_ethercat.ioc.screens import bob
from fastcs_ethercat.ioc.screens.chain import write_screens
from fastcs_ethercat.ioc.screens.pages import (
    MAX_WIDGETS,
    Screen,
    Section,
    Show,
    Value,
    render,
)
from tests.conftest import REPO_ROOT, TERMINALS_DIR
from tests.tree_support import built_tree

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"


Screens = tuple[RootController, dict[str, ElementTree.Element]]
"""The tree and its displays by file name (their `<display>` elements)."""


def count_widgets(tree: ElementTree.ElementTree | ElementTree.Element) -> int:
    """Every widget of a display, those inside groups included."""
    return sum(1 for _ in tree.iter("widget"))


@pytest.fixture(scope="module", params=["default", "every CoE object"])
def screens(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Screens:
    work = tmp_path_factory.mktemp("screens")
    terminals = TERMINALS_DIR
    if request.param != "default":
        terminals = terminals_with_coe(TERMINALS_DIR, work / "terminals")
    root = built_tree(DEMO_CHAIN, terminals)
    written = write_screens(root, work / "opi")
    files = {path.name: _load(path) for path in (work / "opi").glob("*.bob")}
    assert written == len(files)
    return root, files


def test_every_served_pv_is_on_a_screen(screens: Screens) -> None:
    root, files = screens
    shown = {
        element.text
        for tree in files.values()
        for tag in ("pv_name", "y_pv")  # a plot's PV is its trace's
        for element in tree.iter(tag)
        if element.text
    }
    served = {entry.name for entry in root.pvs()}

    assert served - shown == set()
    assert shown - served == set()


def test_no_display_holds_more_than_300_widgets(screens: Screens) -> None:
    _, files = screens
    counts = {name: count_widgets(tree) for name, tree in files.items()}

    assert max(counts.values()) <= MAX_WIDGETS, counts


def test_only_phoebus_widgets_with_the_versions_it_writes(screens: Screens) -> None:
    _, files = screens
    for display in files.values():
        assert display.tag == "display"
        assert display.get("version") == bob.DISPLAY_VERSION
        for widget in display.iter("widget"):
            assert bob.WIDGET_TYPES[widget.get("type", "")] == widget.get("version")
            for key in ("x", "y", "width", "height"):
                assert int(widget.findtext(key, "-1")) >= 0


def test_widgets_sit_inside_their_group_and_display(screens: Screens) -> None:
    _, files = screens
    for name, display in files.items():
        outer = (
            int(display.findtext("width", "0")),
            int(display.findtext("height", "0")),
        )
        for widget in display.findall("widget"):
            assert _fits(widget, outer), (name, widget.findtext("name"))
            inner = (
                int(widget.findtext("width", "0")),
                int(widget.findtext("height", "0")),
            )
            for child in widget.findall("widget"):
                assert _fits(child, inner), (name, child.findtext("name"))


def test_every_button_opens_a_display_that_exists(screens: Screens) -> None:
    _, files = screens
    targets = {
        action.findtext("file")
        for tree in files.values()
        for action in tree.iter("action")
        if action.get("type") == "open_display"
    }

    assert targets and targets <= set(files)
    assert "index.bob" in files


def test_the_overview_lists_the_chain_in_bus_order(screens: Screens) -> None:
    root, files = screens
    overview = files["ETH1.bob"]
    groups = [group.findtext("name") for group in overview.findall("widget")[2:]]
    devices = [
        label.findtext("text")
        for group in overview.findall("widget")[3:]
        for label in group.findall("widget[@type='label']")
    ]
    states = [led for led in overview.iter("widget") if led.find("rules") is not None]
    terminals = sorted(root.terminals(), key=lambda t: t.plan.slave.position)

    assert groups == [
        "Master Device 1 (EtherCAT)",
        "RIO1 Term 1 (EK1100)",
        "RIO18 Term 18 (EK1100)",
        "RIO21 Term 21 (EK1122)",
    ]
    assert devices == [t.path[-1] for t in terminals]
    assert len(states) == len(terminals)
    for led, terminal in zip(states, terminals, strict=True):
        alstate = ":".join([*terminal.path, "AlState"])
        assert led.findtext("pv_name") == alstate
        rules = led.findall("rules/rule")
        assert {rule.get("prop_id") for rule in rules} == {"on_color", "off_color"}
        assert [e.get("bool_exp") for e in rules[0].findall("exp")] == [
            "pvSev0==0",
            "pvSev0==1",
            "pvSev0==2",
        ]
        assert rules[0].findtext("pv_name") == alstate


def test_terminal_pages_group_values_by_channel_and_coe_apart(
    screens: Screens,
) -> None:
    root, files = screens
    el4732 = files["ETH1_RIO1_MOD16.bob"]
    frames = [group.findtext("name") for group in el4732.iter("widget")
              if group.get("type") == "group"]  # fmt: skip
    entries = {w.findtext("pv_name") for w in el4732.iter("widget")
               if w.get("type") == "textentry"}  # fmt: skip
    prefix = root.path[0]

    assert frames == ["Term 16 (EL4732): EL4732", "CH1 Channel 1", "CH2 Channel 2"]
    assert f"{prefix}:ETH1:RIO1:MOD16:CH1:Value" in entries  # an output waveform
    el3104 = next(t for t in root.terminals() if t.path[-1] == "MOD22")
    coe = [name for name in files if name.startswith("ETH1_RIO21_MOD22_CoE")]
    coe_frames = [
        group.findtext("name", "")
        for name in coe
        for group in files[name].iter("widget")
        if group.get("type") == "group"
    ]
    assert bool(coe) == bool(el3104.coe_attributes)
    assert all(frame.startswith("C") and " CoE 0x" in frame for frame in coe_frames)
    if coe:
        assert "C8000 CoE 0x8000 AI Settings" in coe_frames
    terminal_page = files["ETH1_RIO21_MOD22.bob"]
    assert not any(":C8" in (e.text or "") for e in terminal_page.iter("pv_name"))


def test_text_pvs_show_as_text_and_arrays_as_plots(screens: Screens) -> None:
    root, files = screens
    kinds = {entry.name: entry.datatype for entry in root.pvs()}
    text_widgets = [
        widget
        for tree in files.values()
        for widget in tree.iter("widget")
        if widget.get("type") in ("textupdate", "textentry")
    ]
    plots = [w for tree in files.values() for w in tree.iter("widget")
             if w.get("type") == "xyplot"]  # fmt: skip
    prefix = root.path[0]

    strings = [
        w for w in text_widgets if kinds.get(w.findtext("pv_name", "")) == "String"
    ]
    assert len(strings) > 20  # every terminal's Type, AlStateText, NetId, ...
    assert all(w.findtext("format") == bob.STRING_FORMAT for w in strings)
    assert all(w.find("format") is None for w in text_widgets if w not in strings)
    shown_as_text = {w.findtext("pv_name") for w in strings}
    assert f"{prefix}:ETH1:RIO1:MOD5:Type" in shown_as_text
    assert f"{prefix}:NetId" in shown_as_text
    assert plots and all(
        kinds[p.findtext("traces/trace/y_pv", "")] == "Waveform" for p in plots
    )
    assert not [w for w in text_widgets
                if kinds.get(w.findtext("pv_name", "")) == "Waveform"
                and w.get("type") == "textupdate"]  # fmt: skip


def test_units_and_ranges_are_in_the_tooltips_and_on_plot_axes() -> None:
    rows = (
        Value("Volts", "P:V", units="V", limits=(-10.0, 10.0), tooltip="Input"),
        Value("Samples", "P:W", Show.PLOT, units="mA", limits=(0.0, 20.0)),
    )
    ((_, tree),) = render(Screen("T", "Units", (Section("S", rows),)))
    (group,) = _root(tree).findall("widget[@type='group']")
    (plot,) = group.findall("widget[@type='xyplot']")
    inside = (int(group.findtext("width", "0")), int(group.findtext("height", "0")))
    axis = plot.find("y_axes/y_axis")
    assert axis is not None

    assert plot.findtext("traces/trace/y_pv") == "P:W"
    assert axis.findtext("title") == "mA"
    assert (axis.findtext("minimum"), axis.findtext("maximum")) == ("0", "20")
    assert int(plot.findtext("height", "0")) > 100
    assert inside[1] >= 7 * 26 and _fits(plot, inside)  # the plot's rows counted


def test_a_value_tooltip_gives_its_range_and_units(screens: Screens) -> None:
    _, files = screens
    page = files["ETH1_RIO1_MOD5.bob"]
    labels = {w.findtext("text"): w.findtext("tooltip", "") for w in page.iter("widget")
              if w.get("type") == "label"}  # fmt: skip

    assert any(tip.endswith(" V)") and " to " in tip for tip in labels.values()), labels


def test_a_screen_too_big_for_one_display_continues_on_the_next() -> None:
    rows = tuple(Value(f"V{k}", f"P:V{k}", write=True) for k in range(250))
    screen = Screen("T", "Big", (Section("Small", rows[:3]), Section("Huge", rows)))

    pages = render(screen)

    assert [name for name, _ in pages] == ["T.bob", "T_2.bob", "T_3.bob"]
    assert all(count_widgets(tree) <= MAX_WIDGETS for _, tree in pages)
    roots = [_root(tree) for _, tree in pages]
    titles = [g.findtext("name") for display in roots
              for g in display.findall("widget[@type='group']")]  # fmt: skip
    assert titles == ["Small", "Huge (1/3)", "Huge (2/3)", "Huge (3/3)"]
    buttons = [[b.findtext("text") for b in display.findall("widget")
                if b.get("type") == "action_button"] for display in roots]  # fmt: skip
    assert buttons == [["Next page"], ["Previous page", "Next page"], ["Previous page"]]
    shown = [e.text or "" for display in roots for e in display.iter("pv_name")]
    assert sorted(shown) == sorted([f"P:V{k}" for k in range(250)] * 1
                                   + [f"P:V{k}_RBV" for k in range(250)]
                                   + [f"P:V{k}" for k in range(3)]
                                   + [f"P:V{k}_RBV" for k in range(3)])  # fmt: skip


def _load(path: Path) -> ElementTree.Element:
    display = ElementTree.parse(path).getroot()
    assert display is not None
    return display


def _root(
    tree: ElementTree.ElementTree[ElementTree.Element | None],
) -> ElementTree.Element:
    display = tree.getroot()
    assert display is not None
    return display


def _fits(widget: ElementTree.Element, outer: tuple[int, int]) -> bool:
    x, y = int(widget.findtext("x", "0")), int(widget.findtext("y", "0"))
    width, height = (
        int(widget.findtext("width", "0")),
        int(widget.findtext("height", "0")),
    )
    return x + width <= outer[0] and y + height <= outer[1]


def test_without_ca_the_screens_name_pva_pvs(tmp_path: Path) -> None:
    chain = tmp_path / "chain.yaml"
    chain.write_text(DEMO_CHAIN.read_text())
    root = built_tree(chain, transports={"ca": False, "pva": True})

    write_screens(root, tmp_path / "opi", ca=False)

    index = _load(tmp_path / "opi" / "index.bob")
    names = [e.text or "" for e in index.iter("pv_name")]
    assert names and all(name.startswith("pva://") for name in names)
