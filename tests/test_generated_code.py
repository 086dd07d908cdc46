"""Generated code (dataclasses, named tuples, type hints) from the cache file:
the same classes as without it, compiled once, and the builtins back after."""

from __future__ import annotations

import builtins
import collections
import dataclasses
import sys
import typing
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import pytest

from fastcs_ethercat import generated_code
from fastcs_ethercat.cli import app
from fastcs_ethercat.generated_code import cache_generated_code, settle_generated_code

_MODULES = (dataclasses, collections, typing)


@pytest.fixture
def cache_file(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "code" / "cache.marshal"
    settle_generated_code()  # whatever another test left installed
    yield path
    settle_generated_code()


def _make_classes() -> tuple[type, type]:
    @dataclasses.dataclass(frozen=True, slots=True, order=True)
    class Point:
        name: str
        index: int = 0
        tags: tuple[str, ...] = ()

    class Pair(NamedTuple):
        left: int
        right: str = "r"

    return Point, Pair


def _exercise(point: type, pair: type) -> list[object]:
    first, second = point("a", 1), point("a", 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.index = 3  # type: ignore[misc]
    hints = typing.get_type_hints(point)
    return [
        repr(first),
        first < second,
        first == point("a", 1),
        hash(first) == hash(point("a", 1)),
        dataclasses.astuple(second),
        hints["tags"],
        pair(1),
        pair(1, "x")._asdict(),
    ]


def test_classes_behave_the_same_and_compile_once(cache_file: Path) -> None:
    plain = _exercise(*_make_classes())

    cache_generated_code(cache_file)
    first_run = _exercise(*_make_classes())
    settle_generated_code()
    written = cache_file.stat().st_mtime_ns

    cache_generated_code(cache_file)
    active = generated_code._active  # pyright: ignore[reportPrivateUsage]
    assert active is not None
    second_run = _exercise(*_make_classes())

    assert first_run == second_run == plain
    assert active.compiled == 0  # every text was in the file
    assert {mode for mode, _ in active.used} == {"exec", "eval"}
    settle_generated_code()
    assert cache_file.stat().st_mtime_ns == written  # nothing new: not rewritten


def test_settling_gives_the_modules_their_builtins_back(cache_file: Path) -> None:
    cache_generated_code(cache_file)
    assert all(name in module.__dict__ for module, name in _stand_ins())
    cache_generated_code(cache_file)  # once per process

    settle_generated_code()

    assert not any(name in module.__dict__ for module, name in _stand_ins())
    assert dataclasses.__dict__.get("exec", builtins.exec) is builtins.exec
    settle_generated_code()  # again: nothing to do


def test_a_damaged_or_foreign_file_only_costs_the_compiles(cache_file: Path) -> None:
    plain = _exercise(*_make_classes())
    cache_file.parent.mkdir(parents=True)
    for damage in (b"\x00garbage", b"", b"\xe9\x00\x00\x00\x00"):
        cache_file.write_bytes(damage)
        cache_generated_code(cache_file)
        assert _exercise(*_make_classes()) == plain
        settle_generated_code()
    # the last settle wrote a good file again
    cache_generated_code(cache_file)
    active = generated_code._active  # pyright: ignore[reportPrivateUsage]
    assert active is not None and active.code


def test_an_unwritable_cache_is_ignored(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")
    cache_generated_code(blocker / "cache.marshal")
    try:
        assert _exercise(*_make_classes()) == _exercise(*_make_classes())
    finally:
        settle_generated_code()  # cannot write: no error
    assert blocker.read_text() == ""


def test_a_full_file_keeps_only_what_its_process_used(
    cache_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cache_generated_code(cache_file)
    _exercise(*_make_classes())
    dataclasses.__dict__["exec"]("other = 1", {})  # another command's class
    settle_generated_code()

    monkeypatch.setattr(generated_code, "MAX_ENTRIES", 2)
    cache_generated_code(cache_file)
    _exercise(*_make_classes())
    dataclasses.__dict__["exec"]("new = 2", {})
    settle_generated_code()

    cache_generated_code(cache_file)
    active = generated_code._active  # pyright: ignore[reportPrivateUsage]
    assert active is not None
    assert ("exec", "new = 2") in active.code
    assert ("exec", "other = 1") not in active.code
    assert len(active.code) > 2  # the classes' code stayed


def test_compile_calls_other_than_anonymous_text_pass_through(
    cache_file: Path,
) -> None:
    cache_generated_code(cache_file)
    stand_in = typing.__dict__["compile"]
    code = stand_in("x + 1", "named.py", "eval")
    assert code.co_filename == "named.py"
    optimised = stand_in("assert x", "<string>", "exec", optimize=2)
    assert optimised.co_filename == "<string>"
    active = generated_code._active  # pyright: ignore[reportPrivateUsage]
    assert active is not None and active.compiled == 0


def _stand_ins() -> list[tuple[object, str]]:
    return [(dataclasses, "exec"), (collections, "eval"), (typing, "compile")]


def test_a_command_leaves_the_modules_as_it_found_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The entry point settles when its command returns: a test (or a
    caller) running commands in one process keeps plain builtins."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(sys, "argv", ["fastcs-ethercat", "--version"])
    with pytest.raises(SystemExit):
        app()

    assert "fastcs-ethercat" in capsys.readouterr().out
    assert not any(name in module.__dict__ for module, name in _stand_ins())
