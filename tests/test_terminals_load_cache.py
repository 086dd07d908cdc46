"""The content-keyed cache of validated terminal YAML (`terminals.load_cache`)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.terminals import load_cache
from fastcs_ethercat.terminals.files import read_terminal_file
from fastcs_ethercat.terminals.loader import load_terminals

from .test_terminals_support import TERMINALS


@pytest.fixture
def cache_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return load_cache.cache_root()


@pytest.fixture
def el3104(tmp_path: Path) -> Path:
    path = tmp_path / "terminals" / "EL3104.yaml"
    path.parent.mkdir()
    shutil.copy(TERMINALS / "EL3104.yaml", path)
    return path


def test_second_load_comes_from_the_cache_and_equals_a_parse(
    cache_home: Path, el3104: Path
) -> None:
    first = load_cache.read_terminal_file_cached(el3104)
    assert len(list(cache_home.glob("*.pickle"))) == 1
    cached = load_cache.read_terminal_file_cached(el3104)
    assert cached == first == read_terminal_file(el3104)
    assert cached["EL3104"] is not first["EL3104"]  # every load its own objects


def test_registry_is_the_same_with_and_without_the_cache(cache_home: Path) -> None:
    load_terminals([TERMINALS])  # fills the cache
    cached = load_terminals([TERMINALS])
    parsed = load_terminals([TERMINALS], use_cache=False)
    assert [(t.type_name, t.terminal, t.path) for t in cached] == [
        (t.type_name, t.terminal, t.path) for t in parsed
    ]


def test_an_edited_file_is_parsed_again(cache_home: Path, el3104: Path) -> None:
    before = load_cache.read_terminal_file_cached(el3104)["EL3104"]
    text = el3104.read_text()
    el3104.write_text(text.replace("selected: true", "selected: false", 1))
    after = load_cache.read_terminal_file_cached(el3104)["EL3104"]
    assert after != before
    assert after == read_terminal_file(el3104)["EL3104"]
    assert len(list(cache_home.glob("*.pickle"))) == 2


def test_a_broken_file_still_fails_with_its_line_and_is_not_cached(
    cache_home: Path, el3104: Path
) -> None:
    el3104.write_text(el3104.read_text() + "EL3104: {}\n")  # duplicate key
    with pytest.raises(UserError) as error:
        load_cache.read_terminal_file_cached(el3104)
    lines = len(el3104.read_text().splitlines())
    assert f"{el3104}:{lines}:1: duplicate key" in str(error.value)
    assert not list(cache_home.glob("*.pickle"))


def test_a_damaged_entry_is_a_miss(cache_home: Path, el3104: Path) -> None:
    expected = load_cache.read_terminal_file_cached(el3104)
    (entry,) = cache_home.glob("*.pickle")
    entry.write_bytes(b"not a pickle")
    assert load_cache.read_terminal_file_cached(el3104) == expected


def test_an_unwritable_cache_is_ignored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, el3104: Path
) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    assert load_cache.read_terminal_file_cached(el3104) == read_terminal_file(el3104)


def test_a_missing_file_is_a_user_error(cache_home: Path, tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such terminal YAML file"):
        load_cache.read_terminal_file_cached(tmp_path / "EL9999.yaml")
