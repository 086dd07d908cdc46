"""Keep an engineer's comments and blank lines when a terminal file is rewritten.

Every writer (regenerate, select-group, select, coe, the editor) produces the
canonical text from the models; this module then carries the comments of the
file it replaces over to the same keys of the new text, through ruamel.yaml's
round trip (which reproduces the canonical text byte for byte, so a file
without comments is written exactly as before). Items of lists are matched by
what identifies them (a symbol's `name_template`, a CoE object's `index`, a
member's `name`, ...), not by position, so a symbol added by a new ESI revision
does not shift comments onto its neighbours. A comment whose key is gone is
not silently lost: it is returned, with its line, for the caller to name.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import YAMLError
from ruamel.yaml.tokens import CommentToken

from fastcs_ethercat.terminals.yaml_io import SCHEMA_HEADER, format_loc

IDENTITY_KEYS = ("name_template", "index", "subindex", "name", "value")
"""What tells list items apart, in this order (first key an item has)."""


@dataclass(frozen=True)
class DroppedComment:
    """A comment of the old file whose key the new file no longer has."""

    line: int
    """1-based line in the old file."""
    text: str
    key: str
    """Key path it was attached to (`EL3104.symbol_nodes[2].selected`)."""

    def __str__(self) -> str:
        return f"line {self.line}: comment {self.text!r} dropped ({self.key} is gone)"


def _yaml() -> YAML:
    """The round-trip settings that reproduce the canonical layout."""
    yaml = YAML()
    yaml.preserve_quotes = True
    yaml.width = 1_000_000
    yaml.indent(mapping=2, sequence=2, offset=0)
    return yaml


def has_comments(text: str) -> bool:
    """Quick test: a comment or blank line besides the schema header.

    A false positive (a `#` inside a quoted value that looks outside) only
    costs a round trip; it never changes what is written."""
    for line in text.removeprefix(SCHEMA_HEADER).splitlines():
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            return True
        at = line.find(" #")
        while at >= 0:
            before = line[:at]
            if before.count("'") % 2 == 0 and before.count('"') % 2 == 0:
                return True
            at = line.find(" #", at + 1)
    return False


def carry_comments(old_text: str, new_text: str) -> tuple[str, list[DroppedComment]]:
    """`new_text` with the comments and blank lines of `old_text` kept.

    Falls back to `new_text` (naming every comment as dropped) if either
    text cannot be round-tripped."""
    if not has_comments(old_text):
        return new_text, []
    yaml = _yaml()
    try:
        old = yaml.load(old_text)
        new = yaml.load(new_text)
    except YAMLError:
        return new_text, []
    if _dump(yaml, new) != new_text:
        return new_text, _all_comments(old)
    dropped: list[DroppedComment] = []
    _transplant(old, new, (), dropped)
    text = _dump(yaml, new)
    if not text.startswith(SCHEMA_HEADER):
        text = SCHEMA_HEADER + text
    return text, _unique(dropped)


def _dump(yaml: YAML, data: Any) -> str:
    stream = io.StringIO()
    yaml.dump(data, stream)
    return stream.getvalue()


def _identity(item: Any, position: int) -> Hashable:
    if isinstance(item, CommentedMap):
        for key in IDENTITY_KEYS:
            if key in item:
                value = item[key]
                return (key, str(value), str(item.get("channels", "")))
    return ("#", position)


def _pairs(old: CommentedSeq, new: CommentedSeq) -> dict[int, int]:
    """Old position -> new position of the items that are the same item."""
    wanted: dict[Hashable, list[int]] = {}
    for position, item in enumerate(new):
        wanted.setdefault(_identity(item, position), []).append(position)
    pairs: dict[int, int] = {}
    for position, item in enumerate(old):
        free = wanted.get(_identity(item, position))
        if free:
            pairs[position] = free.pop(0)
    return pairs


def _transplant(
    old: Any, new: Any, loc: tuple[Any, ...], dropped: list[DroppedComment]
) -> None:
    if isinstance(old, CommentedMap) and isinstance(new, CommentedMap):
        keys = {key: key for key in old if key in new}
        _move_comments(old, new, keys.get, loc, dropped)
        for key, value in old.items():
            if key in keys:
                _transplant(value, new[key], (*loc, key), dropped)
            else:
                dropped += _all_comments(value, (*loc, key))
    elif isinstance(old, CommentedSeq) and isinstance(new, CommentedSeq):
        pairs = _pairs(old, new)
        _move_comments(old, new, pairs.get, loc, dropped)
        for position, item in enumerate(old):
            if position in pairs:
                _transplant(
                    item, new[pairs[position]], (*loc, pairs[position]), dropped
                )
            else:
                dropped += _all_comments(item, (*loc, position))


def _move_comments(
    old: CommentedMap | CommentedSeq,
    new: CommentedMap | CommentedSeq,
    target: Callable[[Any], Any],
    loc: tuple[Any, ...],
    dropped: list[DroppedComment],
) -> None:
    if old.ca.comment is not None:
        new.ca.comment = old.ca.comment
    if old.ca.end:
        new.ca.end = old.ca.end
    for key, comment in old.ca.items.items():
        moved = target(key)
        if moved is None:
            dropped.extend(_dropped(comment, format_loc((*loc, key))))
        else:
            new.ca.items[moved] = comment


def _tokens(value: Any) -> Iterator[CommentToken]:
    if isinstance(value, CommentToken):
        yield value
    elif isinstance(value, list):
        for item in value:
            yield from _tokens(item)


def _dropped(comment: Any, key: str) -> list[DroppedComment]:
    found: list[DroppedComment] = []
    for token in _tokens(comment):
        text = " ".join(line.strip() for line in token.value.splitlines()).strip()
        if text:
            line = token.start_mark.line + 1 if token.start_mark else 0
            found.append(DroppedComment(line=line, text=text, key=key))
    return found


def _all_comments(data: Any, loc: tuple[Any, ...] = ()) -> list[DroppedComment]:
    found: list[DroppedComment] = []
    if isinstance(data, CommentedMap | CommentedSeq):
        for key, comment in data.ca.items.items():
            found += _dropped(comment, format_loc((*loc, key)))
        children = data.items() if isinstance(data, CommentedMap) else enumerate(data)
        for key, child in children:
            found += _all_comments(child, (*loc, key))
    return _unique(found)


def _unique(found: list[DroppedComment]) -> list[DroppedComment]:
    """ruamel keeps some comments in two places; name each once."""
    seen: set[tuple[int, str]] = set()
    result: list[DroppedComment] = []
    for item in found:
        if (item.line, item.text) not in seen:
            seen.add((item.line, item.text))
            result.append(item)
    return result
