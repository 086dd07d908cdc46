"""PV names for the EtherCAT tree: `<prefix>:<master>:<coupler>:<terminal>:<symbol>`.

Every PV segment is the name of a FastCS sub-controller or attribute, so a
segment has to survive three consumers unchanged: EPICS record names, the PVI
structure (field names) and pvi's .bob screens, whose widget names must match
`^([A-Z][a-z0-9]*)*$`. Hence every segment is PascalCase ASCII: an upper-case
letter followed by letters and digits, no underscores (FastCS's own
snake_case -> PascalCase conversion then leaves it alone).

Default scheme (TwinCAT name -> segment):

- master   `Device 1 (EtherCAT)` -> `ETH1`   (any other name: PascalCase of it)
- coupler  `Term 1 (EK1100)`     -> `RIO1`
- terminal `Term 5 (EL3104)`     -> `MOD5`
- symbol   `AI Standard Channel 1.Value` -> `AIStdCh1Value`: words are joined in
  PascalCase, `Channel` -> `Ch`, `Standard` -> `Std`, `%` -> `Pct`, `°` -> `Deg`,
  `µ` -> `u`, other characters dropped, a repeated member (`WcState.WcState`)
  written once, and a leading digit gets an `N` in front. A symbol's leading
  `<terminal name>.` is dropped.

Aliases pin a segment: the key is the TwinCAT path of a controller or symbol,
its names joined with `^` (`Device 1 (EtherCAT)^Term 1 (EK1100)^Term 5 (EL3104)`
or `...^Term 5 (EL3104)^AI Standard Channel 1.Value`), the value the segment.

Length: every PV, including its `_RBV` twin, stays within 60 characters, so
every base name stays within 56. A node's budget depends only on its
ancestors (so all children of one controller agree on its segment): a
controller takes at most 16 characters and leaves room for the deeper levels
(up to `MAX_CONTROLLER_DEPTH`) at their minimum; a symbol takes what is left. A
segment over budget first loses the inner lower-case vowels of its longest
words (`Underrange` -> `Undrrng`), then is cut and marked with `X` and a hash of
its TwinCAT name (`AIStdCh1StsUX3F2A`). Two siblings that would get the same
segment (compared without case, as PVI lower-cases sub-controller names) both
get hashes of growing length until they differ. Every change from the readable
default is returned in `PvNames.shortened`; nothing is shortened silently.
"""

from __future__ import annotations

import hashlib
import re
import unicodedata
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from functools import lru_cache
from typing import Final

from fastcs_ethercat.errors import UserError

MAX_PV_LENGTH: Final = 60
"""EPICS record names (and FastCS's CA transport) stop at 60 characters."""
RBV_SUFFIX: Final = "_RBV"
"""FastCS serves a read-write attribute as `<name>` plus `<name>_RBV`."""
MAX_BASE_LENGTH: Final = MAX_PV_LENGTH - len(RBV_SUFFIX)
MIN_SEGMENT: Final = 6
"""A shortened controller segment keeps at least one letter plus `X` and a hash."""
MIN_LEAF: Final = 12
"""Room always left for a symbol's segment, whatever the controllers take."""
MAX_CONTROLLER_DEPTH: Final = 3
"""master, coupler, terminal."""
MAX_CONTROLLER_SEGMENT: Final = 16
"""Controllers stay short so that symbols keep their room."""
MAX_PREFIX_LENGTH: Final = (
    MAX_BASE_LENGTH - MAX_CONTROLLER_DEPTH * (1 + MIN_SEGMENT) - (1 + MIN_LEAF)
)
ALIAS_SEPARATOR: Final = "^"
RESERVED_SEGMENTS: Final = frozenset({"pvi"})
"""Lower-cased names FastCS itself serves under every controller (`<path>:PVI`)."""

_HASH_MARK = "X"
_FIRST_HASH_LENGTH = 4
_HASH_LENGTHS: Final = (4, 6, 8, 10)
_PREFIX_RE = re.compile(r"^[A-Za-z0-9_:-]+$")
_SEGMENT_RE = re.compile(r"^[A-Z][A-Za-z0-9]*$")
_WORD_RE = re.compile(r"[A-Za-z0-9]+")
_PASCAL_WORD_RE = re.compile(r"[A-Z][a-z0-9]*|[a-z0-9]+")
_INNER_VOWELS_RE = re.compile(r"(?<=.)[aeiou]")
_ABBREVIATIONS: Final[dict[str, str]] = {"channel": "Ch", "standard": "Std"}
_SPECIAL_CHARACTERS: Final = {"%": " Pct ", "°": " Deg ", "µ": "u", "μ": "u"}


class NodeKind(StrEnum):
    """What a controller of the tree stands for; picks the default scheme."""

    MASTER = "master"
    COUPLER = "coupler"
    TERMINAL = "terminal"


_DEFAULT_PATTERNS: Final = {
    NodeKind.MASTER: (re.compile(r"^Device\s+(\d+)(\s*\(.*\))?$"), "ETH"),
    NodeKind.COUPLER: (re.compile(r"^Term\s+(\d+)(\s*\(.*\))?$"), "RIO"),
    NodeKind.TERMINAL: (re.compile(r"^Term\s+(\d+)(\s*\(.*\))?$"), "MOD"),
}


@dataclass(frozen=True, order=True)
class Node:
    """One controller level: its role and its name in TwinCAT."""

    kind: NodeKind
    name: str


@dataclass(frozen=True, order=True)
class PvRequest:
    """One attribute: the controllers above it and its own (symbol) name."""

    path: tuple[Node, ...]
    leaf: str


@dataclass(frozen=True)
class Shortening:
    """A segment that differs from the readable default, and why."""

    source: str
    """The TwinCAT path (alias key) of the node."""
    default: str
    segment: str
    reason: str

    def __str__(self) -> str:
        return f"{self.source}: {self.default} -> {self.segment} ({self.reason})"


@dataclass(frozen=True)
class PvNames:
    """The planned segments of a whole tree, and what had to be shortened."""

    prefix: str
    controllers: Mapping[tuple[Node, ...], str]
    leaves: Mapping[PvRequest, str]
    shortened: tuple[Shortening, ...]
    unused_aliases: tuple[str, ...] = field(default=())

    def controller_path(self, nodes: tuple[Node, ...]) -> list[str]:
        """The FastCS path of a controller: the prefix, then one segment per level."""
        return [self.prefix] + [
            self.controllers[nodes[: depth + 1]] for depth in range(len(nodes))
        ]

    def pv(self, request: PvRequest) -> str:
        """The full PV name of an attribute (its `_RBV` twin adds 4 characters)."""
        return ":".join([*self.controller_path(request.path), self.leaves[request]])


def alias_key(names: Iterable[str]) -> str:
    """The key that pins a node in the `pv_aliases` configuration."""
    return ALIAS_SEPARATOR.join(names)


@lru_cache(maxsize=65536)
def default_segment(name: str, kind: NodeKind | None = None) -> str:
    """The readable PascalCase segment of a TwinCAT name (kind None: a symbol).

    Cached: every terminal of a type repeats the same symbol names."""
    if kind is not None:
        pattern, stem = _DEFAULT_PATTERNS[kind]
        if match := pattern.match(name.strip()):
            return f"{stem}{int(match.group(1))}"
    parts: list[str] = []
    for part in name.split("."):
        words = _words_of(part)
        segment = "".join(w[0].upper() + w[1:] for w in words)
        if segment and (not parts or parts[-1] != segment):
            parts.append(segment)
    joined = "".join(parts)
    if joined and joined[0].isdigit():
        joined = "N" + joined
    return joined


def plan_pv_names(
    prefix: str,
    requests: Iterable[PvRequest],
    aliases: Mapping[str, str] | None = None,
) -> PvNames:
    """Name every controller and attribute of the tree; deterministic for a set.

    Raises `UserError` for a prefix or an alias that cannot fit; everything
    else is made to fit and reported in `PvNames.shortened`.
    """
    check_prefix(prefix)
    aliases = dict(aliases or {})
    for key, segment in aliases.items():
        check_alias(key, segment)
    request_set = set(requests)  # order-free: siblings are sorted when named
    used: set[str] = set()
    shortened: list[Shortening] = []

    controllers: dict[tuple[Node, ...], str] = {}
    leaves: dict[PvRequest, str] = {}
    children: dict[tuple[Node, ...], set[Node | str]] = defaultdict(set)
    for request in request_set:
        if len(request.path) > MAX_CONTROLLER_DEPTH:
            raise ValueError(f"{request} is deeper than {MAX_CONTROLLER_DEPTH} levels")
        for depth in range(len(request.path)):
            children[request.path[:depth]].add(request.path[depth])
        children[request.path].add(request.leaf)

    def name_children(parent: tuple[Node, ...], parent_pv: str) -> None:
        members = sorted(children[parent], key=_child_sort_key)
        wanted: list[_Wanted] = []
        for child in members:
            if isinstance(child, Node):
                names = [n.name for n in parent] + [child.name]
                cap = _controller_cap(parent_pv, len(parent))
                default = default_segment(child.name, child.kind)
                hash_source = f"{child.kind}:{child.name}"
            else:
                names = [n.name for n in parent] + [_relative_leaf(parent, child)]
                cap = MAX_BASE_LENGTH - len(parent_pv) - 1
                default = default_segment(names[-1])
                hash_source = f"leaf:{child}"
            key = alias_key(names)
            pinned = aliases.get(key)
            if pinned is not None:
                used.add(key)
                if len(pinned) > cap:
                    raise UserError(
                        f"alias {pinned!r} makes a PV longer than {MAX_BASE_LENGTH}"
                        f" characters (+ {RBV_SUFFIX}); at most {cap} fit here",
                        where=f"pv_aliases[{key!r}]",
                    )
            wanted.append(_Wanted(child, key, default, pinned, cap, hash_source))
        resolved = _resolve_siblings(wanted, shortened)
        for index, item in enumerate(wanted):
            segment = resolved[index]
            if isinstance(item.child, Node):
                path = (*parent, item.child)
                controllers[path] = segment
                name_children(path, f"{parent_pv}:{segment}")
            else:
                leaves[PvRequest(parent, item.child)] = segment

    name_children((), prefix)
    return PvNames(
        prefix=prefix,
        controllers=controllers,
        leaves=leaves,
        shortened=tuple(shortened),
        unused_aliases=tuple(sorted(set(aliases) - used)),
    )


def check_prefix(prefix: str) -> None:
    """A prefix is used verbatim: EPICS-legal characters and short enough."""
    if not _PREFIX_RE.match(prefix):
        raise UserError(
            f"PV prefix {prefix!r} may hold only letters, digits, '_', '-' and ':'",
            where="prefix",
        )
    if len(prefix) > MAX_PREFIX_LENGTH:
        raise UserError(
            f"PV prefix {prefix!r} is {len(prefix)} characters; at most"
            f" {MAX_PREFIX_LENGTH} leave room for master, coupler, terminal and"
            f" symbol within {MAX_PV_LENGTH} characters",
            where="prefix",
        )


def check_alias(key: str, segment: str) -> None:
    """An alias must be a segment FastCS, PVI and pvi screens all take as is."""
    if not _SEGMENT_RE.match(segment):
        raise UserError(
            f"alias {segment!r} must be PascalCase: an upper-case letter, then"
            " letters and digits only (EPICS, PVI and .bob screens all need that)",
            where=f"pv_aliases[{key!r}]",
        )


@dataclass(frozen=True)
class _Wanted:
    child: Node | str
    key: str
    default: str
    pinned: str | None
    cap: int
    hash_source: str


def _child_sort_key(child: Node | str) -> tuple[str, str]:
    return (child.kind, child.name) if isinstance(child, Node) else ("~leaf", child)


def _relative_leaf(parent: tuple[Node, ...], leaf: str) -> str:
    """A symbol named `<terminal>.<rest>` is named by `<rest>` under its terminal."""
    if parent and leaf.startswith(parent[-1].name + "."):
        return leaf[len(parent[-1].name) + 1 :]
    return leaf


def _controller_cap(parent_pv: str, depth: int) -> int:
    """Longest segment a controller at `depth` may take, leaving room below it."""
    below = (MAX_CONTROLLER_DEPTH - 1 - depth) * (1 + MIN_SEGMENT) + 1 + MIN_LEAF
    return min(MAX_BASE_LENGTH - len(parent_pv) - 1 - below, MAX_CONTROLLER_SEGMENT)


def _resolve_siblings(
    wanted: list[_Wanted], shortened: list[Shortening]
) -> dict[int, str]:
    """Fit every sibling into its budget and make all siblings distinct.

    Returns the segment of each entry of `wanted`, by position.
    """
    chosen: dict[int, str] = {}
    reasons: dict[int, str] = {}
    pinned_lower: dict[str, str] = {}
    for index, item in enumerate(wanted):
        if item.pinned is None:
            segment, reason = _fit(item.default, item.cap, item.hash_source)
            chosen[index] = segment
            if reason:
                reasons[index] = reason
            continue
        lower = item.pinned.lower()
        if lower in RESERVED_SEGMENTS or lower in pinned_lower:
            other = pinned_lower.get(lower, "FastCS's own PVI record")
            raise UserError(
                f"alias {item.pinned!r} clashes with {other!r} in the same controller",
                where=f"pv_aliases[{item.key!r}]",
            )
        pinned_lower[lower] = item.key
        chosen[index] = item.pinned

    for length in _HASH_LENGTHS:
        clashing = _clashing(wanted, chosen)
        if not clashing:
            break
        for index in clashing:
            item = wanted[index]
            if item.cap >= length + 2:
                base, _ = _fit(item.default, item.cap, item.hash_source)
                chosen[index] = _with_hash(base, item.cap, item.hash_source, length)
                reasons[index] = "made distinct from a sibling with the same name"
    for index in _clashing(wanted, chosen):
        chosen[index] = _numbered(wanted[index], chosen, index)
        reasons[index] = "numbered apart from a sibling with the same name"

    for index, item in enumerate(wanted):
        if index in reasons:
            shortened.append(
                Shortening(item.key, item.default, chosen[index], reasons[index])
            )
    return chosen


def _clashing(wanted: list[_Wanted], chosen: dict[int, str]) -> list[int]:
    """Positions of unpinned siblings whose segment is not unique (without case)."""
    groups: dict[str, list[int]] = defaultdict(list)
    for index in chosen:
        groups[chosen[index].lower()].append(index)
    return sorted(
        index
        for lower, members in groups.items()
        for index in members
        if wanted[index].pinned is None
        and (len(members) > 1 or lower in RESERVED_SEGMENTS)
    )


def _numbered(item: _Wanted, chosen: dict[int, str], index: int) -> str:
    """Last resort when hashes collide: the first free `X<n>` tag."""
    taken = {s.lower() for i, s in chosen.items() if i != index} | RESERVED_SEGMENTS
    base, _ = _fit(item.default, item.cap, item.hash_source)
    number = 0
    while True:
        tag = f"{_HASH_MARK}{number:X}"
        candidate = (base or "N")[: item.cap - len(tag)] + tag
        if candidate.lower() not in taken:
            return candidate
        number += 1


def _fit(default: str, cap: int, hash_source: str) -> tuple[str, str]:
    """The default if it fits; else vowels dropped; else cut and hashed."""
    if not default:
        return _with_hash("", cap, hash_source, _FIRST_HASH_LENGTH), "empty name"
    if len(default) <= cap:
        return default, ""
    compressed = _drop_inner_vowels(default, cap)
    if len(compressed) <= cap:
        return compressed, f"vowels dropped to fit {cap} characters"
    cut = _with_hash(compressed, cap, hash_source, _FIRST_HASH_LENGTH)
    return cut, f"cut to {cap} characters"


def _drop_inner_vowels(segment: str, cap: int) -> str:
    """Drop inner lower-case vowels, longest word first, until it fits."""
    words = _PASCAL_WORD_RE.findall(segment)
    order = sorted(range(len(words)), key=lambda i: (-len(words[i]), i))
    for index in order:
        if sum(map(len, words)) <= cap:
            break
        words[index] = _INNER_VOWELS_RE.sub("", words[index])
    return "".join(words)


def _with_hash(base: str, cap: int, hash_source: str, length: int) -> str:
    """`base` cut so that `X` and `length` hex digits of the hash fit in `cap`."""
    digest = hashlib.sha1(hash_source.encode("utf-8")).hexdigest().upper()
    tag = _HASH_MARK + digest[:length]
    return (base or "N")[: cap - len(tag)] + tag


def _words_of(text: str) -> list[str]:
    for special, replacement in _SPECIAL_CHARACTERS.items():
        text = text.replace(special, replacement)
    ascii_text = (
        unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    )
    words: list[str] = _WORD_RE.findall(ascii_text)
    return [_ABBREVIATIONS.get(word.lower(), word) for word in words]
