"""The terminal editor in a real browser (Debian's Chromium through Selenium).

Opens `terminals edit` on a copy of `terminals/`, adds a type from the ESI
catalog, chooses EL3104, switches it to Compact, unticks its symbol, ticks a
CoE object, shows an error next to a bad name, reviews the diff and saves.
The file must equal what `select-group`/`select`/`coe` write for the same
choices, and `ioc --list-pvs` against the simulator must list exactly the PVs
the editor previewed.

A screenshot of every page is written to `$FASTCS_ETHERCAT_SCREENSHOTS`, by
default `build/screenshots/` in the repository (the folder is printed at the
end of the run); CI's workflow (`.github/workflows/ci.yml`) uploads that
folder as the `editor-screenshots` artefact of every run, pass or fail.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from fastcs_ethercat.editor.pv_preview import preview_pvs
from fastcs_ethercat.process import ChildProcess
from fastcs_ethercat.sim.process import SimProcess
from fastcs_ethercat.terminals.files import read_terminal_file

from .conftest import NEEDS_ESI_SUBSET, SCREENSHOTS
from .ioc_support import ioc_env, new_token, processes_with_token, stop_pid
from .processes import CLI, run_cli_child
from .test_terminals_support import ESI, FIXTURE, TERMINALS, run_cli

pytestmark = pytest.mark.e2e

CHROMIUM = shutil.which("chromium")
CHROMEDRIVER = shutil.which("chromedriver")
if CHROMIUM is None or CHROMEDRIVER is None:
    pytest.skip(
        "needs Debian's Chromium: apt-get install -y chromium chromium-driver",
        allow_module_level=True,
    )
if not ESI.is_dir():
    pytest.skip(NEEDS_ESI_SUBSET, allow_module_level=True)

from selenium import webdriver  # noqa: E402
from selenium.common.exceptions import (  # noqa: E402
    ElementClickInterceptedException,
    ElementNotInteractableException,
    StaleElementReferenceException,
)
from selenium.webdriver.chrome.options import Options  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402
from selenium.webdriver.remote.webelement import WebElement  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402

WIDTH = 1280
"""The narrowest window the pages must fit without scrolling sideways."""
PREFIX = "TSTEDIT:ETH1:RIO1:MOD2"
CHAIN = {
    "system": {"net_id": "127.0.0.1.1.1"},
    "masters": [
        {
            "name": "Device 1 (EtherCAT)",
            "slaves": [{"type": "EK1100"}, {"type": "EL3104", "pdo_group": "Compact"}],
        }
    ],
}


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = tmp_path_factory.mktemp("editor")
    shutil.copytree(TERMINALS, work / "terminals")
    return work


@pytest.fixture(scope="module")
def screenshots(request: pytest.FixtureRequest) -> Iterator[Path]:
    """Where every page's screenshot is kept (printed at the end)."""
    folder = Path(os.environ.get("FASTCS_ETHERCAT_SCREENSHOTS") or SCREENSHOTS)
    folder.mkdir(parents=True, exist_ok=True)
    yield folder
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    with capture.global_and_fixture_disabled() if capture else contextlib.nullcontext():
        print(f"\neditor screenshots: {folder}")


@contextlib.contextmanager
def running_editor(folder: Path, cache: Path, *extra: str) -> Iterator[str]:
    """`terminals edit FOLDER` on loopback and a free port: its URL."""
    env = dict(os.environ, XDG_CACHE_HOME=str(cache), PYTHONUNBUFFERED="1")
    env.pop("PYTEST_CURRENT_TEST", None)  # NiceGUI would take it for its own tests
    command = [*CLI, "terminals", "edit", str(folder), "--esi", str(ESI),
               "--esi", str(FIXTURE), "--port", "0", *extra]  # fmt: skip
    child = ChildProcess(command, "terminals edit", env=env, merge_stderr=True)
    try:
        url = child.start(90)["url"]
        assert url.startswith("http://127.0.0.1:")
        yield url
    finally:
        child.close()


@pytest.fixture(scope="module")
def editor(work: Path) -> Iterator[str]:
    with running_editor(work / "terminals", work / "cache") as url:
        yield url


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    options = Options()
    assert CHROMIUM is not None and CHROMEDRIVER is not None
    options.binary_location = CHROMIUM
    size = f"--window-size={WIDTH},1000"
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu",
                     "--disable-dev-shm-usage", size):  # fmt: skip
        options.add_argument(argument)
    browser = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield browser
    finally:
        browser.quit()


def find(driver: Any, name: str, timeout: float = 20) -> WebElement:
    """The element marked `data-test=name`, once it is there."""
    selector = f'[data-test="{name}"]'
    return WebDriverWait(driver, timeout).until(
        lambda d: d.find_element(By.CSS_SELECTOR, selector)
    )


def field(driver: Any, name: str) -> WebElement:
    """The native <input> of a marked input (Quasar puts the mark on it)."""
    found = find(driver, name)
    if found.tag_name == "input":
        return found
    return found.find_element(By.TAG_NAME, "input")


def wait(check: Callable[[], bool], timeout: float = 20) -> None:
    """Until `check()`; an element replaced while it is read (the page redraws
    a section after each choice), or covered for a moment while a section
    grows, only means "look again"."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            if check():
                return
        except (
            StaleElementReferenceException,
            ElementClickInterceptedException,
            ElementNotInteractableException,  # an expansion still opening
        ):
            pass
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.1)


def click(driver: Any, name: str) -> None:
    """Click the marked element, finding it again if a redraw replaced it."""

    def clicked() -> bool:
        find(driver, name).click()
        return True

    wait(clicked)


def save(driver: Any) -> None:
    """Press the review dialog's Save until the page says "saved". A click
    can land while the dialog is still opening and do nothing (CI saw one
    wait 20 s for a save that never came): after a second without a
    change, the button, if still there, is pressed again (a second save of
    saved edits writes nothing)."""
    pressed = [0.0]

    def saved() -> bool:
        if find(driver, "state").text == "saved":
            return True
        buttons = driver.find_elements(By.CSS_SELECTOR, '[data-test="save"]')
        if buttons and time.monotonic() - pressed[0] > 1.0:
            pressed[0] = time.monotonic()
            buttons[0].click()
        return False

    try:
        wait(saved)
    except AssertionError:
        errors = driver.find_elements(By.CSS_SELECTOR, '[data-test="save-error"]')
        said = [error.text for error in errors]
        state = find(driver, "state").text
        raise AssertionError(f"not saved: state {state!r}, errors {said}") from None


def add_from_search(driver: Any, search: WebElement, type_name: str) -> None:
    """Type an exact type name in the catalog search, click its "Add"."""
    search.send_keys(Keys.CONTROL, "a")
    search.send_keys(type_name)

    def add() -> bool:
        buttons = driver.find_elements(By.CSS_SELECTOR, 'button[data-test^="add-"]')
        names = [b.get_attribute("data-test") for b in buttons]
        if names != [f"add-{type_name}"]:
            return False
        buttons[0].click()
        return True

    wait(add)


def choose(
    driver: Any, name: str, text: str, done: Callable[[], bool] | None = None
) -> None:
    """Pick `text` in the marked select's menu (until `done()`, if given: the
    redraw a choice makes can turn the clicked item stale mid-click, or close
    a menu opened just before it; then it is opened again)."""
    click(driver, name)
    empty = [0]

    def pick() -> bool:
        if done is not None and done():
            return True
        items = driver.find_elements(By.CSS_SELECTOR, ".q-menu .q-item")
        item = next((e for e in items if e.text.strip() == text), None)
        if item is None:
            empty[0] += 1
            if done is not None and empty[0] % 10 == 0:
                find(driver, name).click()
            return False
        item.click()
        return done is None

    wait(pick)


def type_into(driver: Any, name: str, *keys: str) -> None:
    """Type into the marked input, finding it again if a redraw replaced it."""

    def typed() -> bool:
        field(driver, name).send_keys(*keys)
        return True

    wait(typed)


def checked(element: WebElement) -> bool:
    return element.get_attribute("aria-checked") == "true"


def test_editor_session_matches_the_cli_and_the_ioc(
    editor: str, driver: Any, work: Path, screenshots: Path
) -> None:
    folder = work / "terminals"
    driver.get(editor)
    find(driver, "open-EL3104")
    assert "1 of 2" in find(driver, "types").text
    driver.save_screenshot(str(screenshots / "00-types.png"))

    # add a type from the catalog: one that exists is refused next to the field
    search = field(driver, "search")
    search.send_keys("ana. output")
    driver.execute_script("arguments[0].scrollIntoView()", find(driver, "add-EL4134"))
    driver.save_screenshot(str(screenshots / "01-search.png"))
    add_from_search(driver, search, "EL4134")
    wait(lambda: "exists already" in find(driver, "add-error").text)
    add_from_search(driver, search, "EL3102")
    find(driver, "symbols")
    assert driver.current_url.endswith("/type/EL3102")
    assert "written when you save" in find(driver, "pending").text
    assert find(driver, "state").text == "new, not saved"
    assert not (folder / "EL3102.yaml").exists()  # nothing before Save
    driver.save_screenshot(str(screenshots / "02-added-EL3102.png"))
    click(driver, "review")
    wait(lambda: "selected_pdo_group: Standard" in find(driver, "diff").text)
    save(driver)
    added = read_terminal_file(folder / "EL3102.yaml")["EL3102"]
    default = added.default_group
    assert default is not None and added.selected_pdo_group == default.name
    assert [n.selected for n in added.symbol_nodes] == [
        i in default.symbol_indices for i in range(len(added.symbol_nodes))
    ]

    # a type that is not there is a message, not a traceback page
    driver.get(f"{editor}type/NOPE")
    assert "no terminal type 'NOPE'" in find(driver, "page-error").text

    # the oversampling factor, then back to the file as it is
    driver.get(f"{editor}type/EL3702")
    choose(driver, "factor", "20")
    wait(lambda: find(driver, "state").text == "unsaved changes")
    assert "x 20 samples" in find(driver, "symbol-facts-1").text
    driver.save_screenshot(str(screenshots / "03-EL3702-factor.png"))
    driver.get(editor)  # leave it unsaved: the index and the next visit say so
    assert "EL3702" in find(driver, "pending").text
    driver.get(f"{editor}type/EL3702")
    assert "edits not saved yet" in find(driver, "pending").text
    driver.save_screenshot(str(screenshots / "03b-EL3702-pending.png"))
    click(driver, "discard")
    wait(lambda: find(driver, "state").text == "saved")
    assert "x 10 samples" in find(driver, "symbol-facts-1").text

    driver.get(f"{editor}type/EL3104")
    choose(driver, "group", "Compact")
    wait(lambda: checked(find(driver, "symbol-1")))
    click(driver, "symbol-1")
    wait(lambda: not checked(find(driver, "symbol-1")))
    assert checked(find(driver, "coe-0x8000"))  # shipped: 0x8000:06 alone
    click(driver, "coe-0x8000")
    wait(lambda: not checked(find(driver, "coe-0x8000")))
    click(driver, "coe-0x8000")  # on again: the whole object
    wait(lambda: checked(find(driver, "coe-0x8000")))
    prefix = field(driver, "prefix")
    prefix.send_keys(Keys.CONTROL, "a")
    prefix.send_keys(PREFIX, Keys.TAB)  # leaving the field applies it
    wait(lambda: PREFIX in find(driver, "coe-pvs-0x8000").text)
    name = field(driver, "name-1")
    name.send_keys(Keys.CONTROL, "a")
    name.send_keys("Bad Name", Keys.TAB)
    wait(lambda: "is not a fastcs_name" in find(driver, "symbol-error-1").text)
    assert "unsaved changes" in find(driver, "state").text
    driver.save_screenshot(str(screenshots / "04-EL3104-compact.png"))

    click(driver, "review")
    diff = find(driver, "diff")
    wait(lambda: "selected_pdo_group: Compact" in diff.text)
    driver.save_screenshot(str(screenshots / "05-diff.png"))
    save(driver)
    driver.save_screenshot(str(screenshots / "06-saved.png"))

    # the same choices from the command line give the same bytes
    by_cli = work / "cli" / "EL3104.yaml"
    by_cli.parent.mkdir()
    shutil.copy(TERMINALS / "EL3104.yaml", by_cli)
    assert run_cli("terminals", "select-group", str(by_cli), "Compact").code == 0
    assert run_cli("terminals", "select", str(by_cli), "--off",
                   "AI Compact Channel {channel}").code == 0  # fmt: skip
    assert run_cli("terminals", "coe", str(by_cli), "0x8000").code == 0
    assert (folder / "EL3104.yaml").read_bytes() == by_cli.read_bytes()

    # and the IOC serves exactly the PVs the editor showed
    saved = read_terminal_file(folder / "EL3104.yaml")["EL3104"]
    expected = set()
    for preview in preview_pvs(saved, "EL3104", PREFIX):
        expected |= {preview.pv, *([f"{preview.pv}_RBV"] if preview.writable else [])}
    served = _served_pvs(work, folder)
    assert served == expected


def _served_pvs(work: Path, folder: Path) -> set[str]:
    """`ioc --list-pvs` of the edited files against a simulated EL3104."""
    chain = work / "chain.yaml"
    chain.write_text(yaml.safe_dump(CHAIN), encoding="utf-8")
    token = new_token()
    env = ioc_env(token)
    try:
        with SimProcess(chain=chain, terminals=folder, env=env) as sim:
            config = work / "ioc.yaml"
            config.write_text(
                yaml.safe_dump(
                    {
                        "prefix": PREFIX.split(":")[0],
                        "target": sim.pyads_ip,
                        "ams_net_id": sim.net_id,
                        "terminal_dirs": [str(folder)],
                        "ads_timeout_ms": 5000,  # a loaded shared machine
                    }
                ),
                encoding="utf-8",
            )
            done = run_cli_child("ioc", "--config", config, "--list-pvs", env=env)
    finally:
        for pid in processes_with_token(token):
            stop_pid(pid)
    assert done.returncode == 0, done.stderr[-2000:]
    served = set()
    for line in done.stdout.splitlines():
        pv, _access, _kind, source = line.split(" ", 3)
        ours = pv.startswith(f"{PREFIX}:") and not pv.endswith(":CoeRefresh")
        if ours and source != "ioc" and ".WcState." not in source:
            served.add(pv)
    return served


def test_target_shows_each_live_terminal_and_a_mismatch(
    driver: Any, tmp_path: Path, screenshots: Path
) -> None:
    """EL3104's file selects Standard; the simulated terminal runs Compact."""
    folder = tmp_path / "terminals"
    shutil.copytree(TERMINALS, folder)
    chain = tmp_path / "chain.yaml"
    chain.write_text(yaml.safe_dump(CHAIN), encoding="utf-8")
    with (
        SimProcess(chain=chain, terminals=folder) as sim,
        running_editor(
            folder,
            tmp_path / "cache",
            "--target",
            sim.pyads_ip,
            "--ams-net-id",
            sim.net_id,
        ) as url,  # fmt: skip
    ):
        driver.get(f"{url}type/EL3104")
        live = find(driver, "live-Term 2 (EL3104)")
        assert live.text == (
            "Term 2 (EL3104): runs Compact - the file selects Standard: MISMATCH"
        )
        driver.save_screenshot(str(screenshots / "07-live-mismatch.png"))
        choose(driver, "group", "Compact")
        wait(lambda: "MISMATCH" not in find(driver, "live-Term 2 (EL3104)").text)


def test_units_and_severities_from_the_editor_match_the_cli(
    editor: str, driver: Any, work: Path, screenshots: Path
) -> None:
    """EL3124's value in A instead of mA and its Error bit MINOR: the same
    bytes as `terminals units` and `terminals severity` write."""
    folder = work / "terminals"
    driver.get(f"{editor}type/EL3124")
    click(driver, "pdo-toggle-0")  # members are collapsed under their PDO
    click(driver, "meaning-toggle-0")
    members = lambda: find(driver, "members-0").text  # noqa: E731
    type_into(driver, "unit-0-8", "A", Keys.TAB)  # member 8: Value (4-20 mA)
    wait(lambda: "x 0.000488296 +4 A" in members())
    type_into(driver, "scale-0-8", "4.8829e-7", Keys.TAB)
    wait(lambda: "x 4.8829e-07 +4 A" in members())
    type_into(driver, "offset-0-8", "0.004", Keys.TAB)
    wait(lambda: "x 4.8829e-07 +0.004 A" in members())
    error_minor = re.compile(r"Status\.Error\s+BIT\s+6\s+1\s+raw\s+minor")
    choose(  # member 4: Status.Error
        driver,
        "severity-0-4",
        "minor",
        done=lambda: bool(error_minor.search(members())),
    )
    type_into(driver, "precision-0-8", "many", Keys.TAB)
    wait(lambda: "is not a number" in find(driver, "meaning-error-0-8").text)
    driver.save_screenshot(str(screenshots / "08-EL3124-units.png"))
    type_into(driver, "precision-0-8", Keys.CONTROL, "a")
    type_into(driver, "precision-0-8", Keys.DELETE, Keys.TAB)
    wait(lambda: not find(driver, "meaning-error-0-8").text)
    click(driver, "review")
    wait(lambda: "unit: A" in find(driver, "diff").text)
    save(driver)

    by_cli = work / "cli-units" / "EL3124.yaml"
    by_cli.parent.mkdir()
    shutil.copy(TERMINALS / "EL3124.yaml", by_cli)
    symbol = "AI Standard Channel {channel}"
    assert run_cli("terminals", "units", str(by_cli), symbol, "--unit", "A",
                   "--scale", "4.8829e-7", "--offset", "0.004").code == 0  # fmt: skip
    assert run_cli("terminals", "severity", str(by_cli), symbol, "minor",
                   "--member", "Status.Error").code == 0  # fmt: skip
    assert (folder / "EL3124.yaml").read_bytes() == by_cli.read_bytes()


def _rows(driver: Any, prefix: str) -> list[str]:
    """`data-row` of the shown rows whose `data-test` starts with `prefix`
    (symbols: `symbol-`, CoE objects: `coe-0x`; not their sub-indices)."""
    rows = driver.find_elements(By.CSS_SELECTOR, f'[data-test^="{prefix}"][data-row]')
    return [row.get_attribute("data-row") or "" for row in rows]


def _filter(driver: Any, text: str) -> None:
    box = field(driver, "filter")
    box.send_keys(Keys.CONTROL, "a")
    box.send_keys(Keys.DELETE)
    if text:
        box.send_keys(text)


def test_the_filter_narrows_elm3704s_lists_to_the_matching_rows(
    editor: str, driver: Any, screenshots: Path
) -> None:
    """ELM3704-0000 has 54 symbols and 62 CoE objects: a word finds its rows."""
    driver.get(f"{editor}type/ELM3704-0000")
    find(driver, "symbols")
    every_symbol, every_object = _rows(driver, "symbol-"), _rows(driver, "coe-0x")
    assert len(every_object) == 62 and len(every_symbol) > 30

    _filter(driver, "timestamp")
    settings = [f"0x80{c}0 PAI Settings Ch.{c + 1}" for c in range(4)]
    wait(lambda: _rows(driver, "coe-0x") == settings, 60)  # by a sub-index's name
    wait(lambda: _rows(driver, "symbol-") == ["PAI Timestamp Channel {channel}"] * 2)
    subs = driver.find_elements(By.CSS_SELECTOR, '[data-test^="coe-0x8000:"]')
    assert [s.text for s in subs if s.is_displayed()] == [
        "34 Timestamp Correction (DINT)"
    ]  # the object opens on its one matching sub-index
    driver.save_screenshot(str(screenshots / "09-ELM3704-filter.png"))

    click(driver, "filter-state")  # the toggle's buttons: all, selected, ...
    buttons = find(driver, "filter-state").find_elements(By.TAG_NAME, "button")
    next(b for b in buttons if b.text.strip() == "selected").click()
    wait(lambda: _rows(driver, "coe-0x") == ["0x8000 PAI Settings Ch.1"])  # selected
    wait(lambda: _rows(driver, "symbol-") == ["PAI Timestamp Channel {channel}"])
    next(b for b in buttons if b.text.strip() == "all").click()

    _filter(driver, "underrange")  # a member: its symbol, opened on that row
    wait(lambda: _rows(driver, "symbol-") == ["PAI Status Channel {channel}"])
    wait(lambda: "Status.Underrange" in find(driver, "members-0").text)
    assert "Status.Overrange" not in find(driver, "members-0").text
    wait(lambda: _rows(driver, "coe-0x") == [])


def _scrolls_sideways(driver: Any) -> bool:
    return bool(
        driver.execute_script(
            "const e = document.documentElement;return e.scrollWidth > e.clientWidth;"
        )
    )


def test_every_page_fits_1280_pixels_without_scrolling_sideways(
    editor: str, driver: Any, screenshots: Path
) -> None:
    assert driver.execute_script("return window.innerWidth") == WIDTH
    driver.get(editor)
    find(driver, "types")
    assert not _scrolls_sideways(driver)
    for name in ("EL3104", "ELM3704-0000", "EL3702", "EL1502"):
        driver.get(f"{editor}type/{name}")
        find(driver, "symbols")
        toggles = 'div[data-test^="pdo-toggle-"]'
        first = driver.find_elements(By.CSS_SELECTOR, toggles)[0]
        position = (first.get_attribute("data-test") or "").rpartition("-")[2]
        click(driver, f"pdo-toggle-{position}")  # its members open, PVs included
        members = f"members-{position}"
        wait(lambda m=members: find(driver, m).is_displayed())
        assert not _scrolls_sideways(driver), name
        driver.save_screenshot(str(screenshots / f"10-{name}-{WIDTH}px.png"))
