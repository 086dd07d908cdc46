"""The parser's model stays exactly what it was (see `tests/esi_model_digest`):
every device of the ESI the tests ship, and of `../shared/esi` when present,
digested field by field against the digests of the model before the speed
work; and the memo's keys cut from a parent's serialisation."""

from __future__ import annotations

import json
from pathlib import Path

from fastcs_ethercat.esi import EsiEnumItem, EsiPdoGroup
from fastcs_ethercat.esi.memo import child_keys
from tests.esi_model_digest import (
    DIGESTS_FILE,
    outline,
    shared_digests,
    shipped_digests,
)


def expected(part: str) -> dict[str, str]:
    return json.loads(DIGESTS_FILE.read_text())[part]


def differing(found: dict[str, str], wanted: dict[str, str]) -> list[str]:
    keys = sorted(set(found) | set(wanted))
    return [key for key in keys if found.get(key) != wanted.get(key)]


def test_every_shipped_device_parses_to_the_pinned_model() -> None:
    assert differing(shipped_digests(), expected("shipped")) == []


def test_every_shared_device_parses_to_the_pinned_model(shared_esi: Path) -> None:
    found = shared_digests()
    assert len(found) == 506
    assert differing(found, expected("shared")) == []


def test_the_outline_names_classes_fields_and_order() -> None:
    """Two values that differ only in class, field or mapping order differ."""
    item = EsiEnumItem(value=1, text="On")
    assert outline(item, "/") == ["EsiEnumItem", ["value", 1], ["text", "On"]]
    assert outline((item,), "/") != outline([1, "On"], "/")
    group = EsiPdoGroup(
        name="A", is_default=True, pdo_indices=(1, 2), sm_pdos={3: (1,), 2: (2,)}
    )
    swapped = EsiPdoGroup(
        name="A", is_default=True, pdo_indices=(1, 2), sm_pdos={2: (2,), 3: (1,)}
    )
    assert outline(group, "/") != outline(swapped, "/")
    assert outline("/esi/EL1xxx.xml", "/esi/") == "EL1xxx.xml"


def test_child_keys_are_cut_only_where_each_child_is_certain() -> None:
    """The memo's keys for children, cut from the parent's serialisation."""
    assert child_keys("<P><E>1</E><E a='2'>2</E></P>", "E", 2) == [
        "<E>1",
        "<E a='2'>2",
    ]
    # each key is its element's text (an attribute's `>` is escaped)
    assert child_keys('<P a="1&gt;"><X/><E>1</E></P>', "E", 1) == ["<E>1"]
    # elements deeper down are cut alike when they are the only ones
    assert child_keys("<O><I><S>1</S><S>2</S></I></O>", "S", 2) == ["<S>1", "<S>2"]
    # the parent may share the name's start
    assert child_keys("<Es><E>1</E></Es>", "E", 1) == ["<E>1"]
    assert child_keys("<P><E><E>x</E></E></P>", "E", 1) is None  # nested
    assert child_keys("<P><E/><E>1</E></P>", "E", 2) is None  # empty child
    assert child_keys("<P><E>1</E></P>", "E", 2) is None  # count differs
    assert child_keys("<P><EX/><E>1</E></P>", "E", 1) is None  # alike name
    # an empty one elsewhere would shift which end closes which element
    assert child_keys("<P><E/><X><E>x</E></X><E>1</E></P>", "E", 2) is None
