"""PV names for the EtherCAT tree, short and stable by construction.

`<prefix>:<master>:<coupler>:<terminal>[:<channel>]:<name>`, e.g.
`BL21I-EA-ECAT-01:ETH1:RIO1:MOD5:CH1:Value`. Every segment is the name of a
FastCS sub-controller or attribute, so a segment has to survive three
consumers unchanged: EPICS record names, the PVI structure (field names) and
.bob screens, whose widget names must match `^([A-Z][a-z0-9]*)*$`. Hence
every segment is PascalCase ASCII: an upper-case letter followed by letters
and digits, no underscores (FastCS's own snake_case -> PascalCase conversion
then leaves it alone).

Segments (TwinCAT name -> segment):

- master   `Device 1 (EtherCAT)` -> `ETH1`   (any other name: PascalCase of it)
- coupler  `Term 1 (EK1100)`     -> `RIO1`
- terminal `Term 5 (EL3104)`     -> `MOD5`
- channel  the terminal's channel 1 (its YAML's `{channel}`) -> `CH1`
- CoE object 0x8000 -> `C8000`, its sub-items below it
- a value: the ESI entry it reads, without the channel and without a leading
  `Status`/`Control` group: `AI Standard Channel 1.Status.Underrange` ->
  `CH1:Underrange`, `AI Compact Channel 1` (entry `Value`) -> `CH1:Value`.
  Words are joined in PascalCase, `Channel` -> `Ch`, `Standard` -> `Std`,
  `%` -> `Pct`, `°` -> `Deg`, `µ` -> `u`, other characters dropped, a
  repeated member (`WcState.WcState`) written once, a leading digit gets an
  `N` in front. Where two values of one controller would get the same name,
  both take their next longer name (`StatusError`, then the whole symbol).

Length, by construction: every level has one budget for the whole IOC, the
longest standard segment of that level in it (`ETH<n>`, `RIO<n>`, `MOD<n>`,
`CH<n>`; at least `MIN_BUDGET`: 4, 5, 5 and 3 characters; `C<index>` 5), and
a value's room is what the prefix and the budgets of all the levels above it
leave, present or not, `_RBV` kept for writable ones. It does not depend on
where the terminal sits (`MOD5` or `MOD105`, behind a coupler or not), so a
terminal type gets the same suffixes everywhere in the IOC; a chain that
grows past `Term 99` gives every value one character less room (a name at
its limit then changes, and says so). A level longer than its budget (an
alias, a terminal TwinCAT calls by a name of its own) takes its room from
the values below it only. Only a name over its room is shortened
(`shorten.fit`: vowels, then cut words, last a hash of its TwinCAT name);
each is returned in `PvNames.shortened`, nothing silent.

Aliases pin a segment: the key is the TwinCAT path of a master, coupler,
terminal or value, its names joined with `^`
(`Device 1 (EtherCAT)^Term 1 (EK1100)^Term 5 (EL3104)` or
`...^Term 5 (EL3104)^AI Standard Channel 1.Value`; a CoE value
`...^Coe <attribute>`), the value the segment; a value keeps its channel or
CoE object. An alias equal to a sibling's name (alias or generated, compared
without case as PVI lower-cases sub-controller names) stops the IOC with one
line naming both.
"""

from __future__ import annotations

import re
import unicodedata
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from functools import lru_cache
from typing import Final

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.plan import CoePoint, Point
from fastcs_ethercat.ioc.shorten import (
    HASH_LENGTHS,
    drop_inner_vowels,
    fit,
    numbered,
    with_hash,
)

MAX_PV_LENGTH: Final = 60
"""EPICS record names (and FastCS's CA transport) stop at 60 characters."""
RBV_SUFFIX: Final = "_RBV"
"""FastCS serves a read-write attribute as `<name>` plus `<name>_RBV`."""
MAX_BASE_LENGTH: Final = MAX_PV_LENGTH - len(RBV_SUFFIX)
COE_LEAF_PREFIX: Final = "Coe "
MIN_LEAF: Final = 8
"""Room always left for a writable value's name, whatever the prefix."""
MAX_CONTROLLER_SEGMENT: Final = 16
"""A master, coupler or terminal with a name of its own stays this short."""
ALIAS_SEPARATOR: Final = "^"
RESERVED_SEGMENTS: Final = frozenset({"pvi", "pvi_pv"})
"""Lower-cased names served under every controller for PVI (`<path>:PVI`,
the structure, and `<path>:PVI_PV`, the record naming it: `ioc.pvi`)."""
GROUP_WORDS: Final = frozenset({"status", "control"})
"""The ESI's bit-field groups (`Status__Underrange`): left out of value names."""


class NodeKind(StrEnum):
    """What a controller of the tree stands for; picks its segment and budget."""

    MASTER = "master"
    COUPLER = "coupler"
    TERMINAL = "terminal"
    CHANNEL = "channel"
    """A terminal's channel: `name` is its number."""
    COE_OBJECT = "coe"
    """A terminal's CoE object: `name` is its index, 4 hex digits."""


TWINCAT_KINDS: Final = frozenset({NodeKind.MASTER, NodeKind.COUPLER, NodeKind.TERMINAL})
"""Levels that are TwinCAT objects: their names make the alias keys."""
MIN_BUDGET: Final = {
    NodeKind.MASTER: 4,  # ETH1 .. ETH9
    NodeKind.COUPLER: 5,  # RIO1 .. RIO99
    NodeKind.TERMINAL: 5,  # MOD1 .. MOD99
    NodeKind.CHANNEL: 3,  # CH1 .. CH9
    NodeKind.COE_OBJECT: 5,  # C0000 .. CFFFF
}
"""The least each level is budgeted; a longer standard segment anywhere in
the IOC (`MOD105`, `CH16`) raises its level's budget for every node."""
_PREFIX_BUDGET: Final = {**MIN_BUDGET, NodeKind.COUPLER: 6, NodeKind.TERMINAL: 6}
"""The budgets `MAX_PREFIX_LENGTH` leaves room for: racks of up to 999 terminals."""
_STANDARD_SEGMENT = re.compile(r"^(ETH|RIO|MOD|CH)\d+$|^C[0-9A-F]{4}$")
_LEVELS: Final = {
    NodeKind.MASTER: (NodeKind.MASTER,),
    NodeKind.COUPLER: (NodeKind.MASTER, NodeKind.COUPLER),
    NodeKind.TERMINAL: (NodeKind.MASTER, NodeKind.COUPLER, NodeKind.TERMINAL),
    NodeKind.CHANNEL: (
        NodeKind.MASTER,
        NodeKind.COUPLER,
        NodeKind.TERMINAL,
        NodeKind.CHANNEL,
    ),
    NodeKind.COE_OBJECT: (
        NodeKind.MASTER,
        NodeKind.COUPLER,
        NodeKind.TERMINAL,
        NodeKind.COE_OBJECT,
    ),
}
"""The levels a path down to a node of each kind is budgeted for: always the
full depth, so a terminal without a coupler names its values as one behind
a coupler does."""


Budgets = Mapping[NodeKind, int]


def _path_budget(kind: NodeKind, budgets: Budgets) -> int:
    """Characters the levels down to a node of `kind` are budgeted, colons too."""
    return sum(1 + budgets[level] for level in _LEVELS[kind])


MAX_PREFIX_LENGTH: Final = (
    MAX_BASE_LENGTH - _path_budget(NodeKind.COE_OBJECT, _PREFIX_BUDGET) - (1 + MIN_LEAF)
)
"""The longest prefix that leaves `MIN_LEAF` for every value."""

_PREFIX_RE = re.compile(r"^[A-Za-z0-9_:-]+$")
_SEGMENT_RE = re.compile(r"^[A-Z][A-Za-z0-9]*$")
_WORD_RE = re.compile(r"[A-Za-z0-9]+")
_ABBREVIATIONS: Final[dict[str, str]] = {"channel": "Ch", "standard": "Std"}
_SPECIAL_CHARACTERS: Final = {"%": " Pct ", "°": " Deg ", "µ": "u", "μ": "u"}
_DEFAULT_PATTERNS: Final = {
    NodeKind.MASTER: (re.compile(r"^Device\s+(\d+)(\s*\(.*\))?$"), "ETH"),
    NodeKind.COUPLER: (re.compile(r"^Term\s+(\d+)(\s*\(.*\))?$"), "RIO"),
    NodeKind.TERMINAL: (re.compile(r"^Term\s+(\d+)(\s*\(.*\))?$"), "MOD"),
}


@dataclass(frozen=True, order=True)
class Node:
    """One controller level: its role and its name (TwinCAT's, a channel
    number or a CoE index)."""

    kind: NodeKind
    name: str


def channel_node(channel: int) -> Node:
    """The controller of a terminal's channel `channel` (`CH<n>`)."""
    return Node(NodeKind.CHANNEL, str(channel))


def coe_node(index: int) -> Node:
    """The controller of a terminal's CoE object `index` (`C<index>`)."""
    return Node(NodeKind.COE_OBJECT, f"{index:04X}")


@dataclass(frozen=True, order=True)
class PvRequest:
    """One attribute: the controllers above it, its TwinCAT name and the
    readable names to try for it."""

    path: tuple[Node, ...]
    leaf: str
    """Its name in TwinCAT: a symbol, a diagnostic, `Coe <attribute>`; the
    last part of its alias key."""
    names: tuple[str, ...] = ()
    """Readable names to try, shortest first, in TwinCAT's words (() -> the
    leaf, without its terminal's name)."""
    writable: bool = False
    """Served with an `_RBV` twin: its room keeps 4 characters for it."""


@dataclass(frozen=True)
class Shortening:
    """A segment that differs from its readable name, and why."""

    source: str
    """The TwinCAT path (alias key) of the node."""
    default: str
    segment: str
    reason: str
    hashed: bool = False
    """Cut and marked with a hash (or a number), not only made shorter."""
    node: tuple[Node, ...] | PvRequest | None = None
    """The controller's path, or the attribute's request."""

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

    def below(self, request: PvRequest, depth: int) -> tuple[str, ...]:
        """The segments of an attribute below the first `depth` levels of its
        path (its channel or CoE object, then its own)."""
        deeper = [
            self.controllers[request.path[: level + 1]]
            for level in range(depth, len(request.path))
        ]
        return (*deeper, self.leaves[request])


def alias_key(names: Iterable[str]) -> str:
    """The key that pins a node in the `pv_aliases` configuration."""
    return ALIAS_SEPARATOR.join(names)


def symbol_request(
    path: tuple[Node, ...],
    symbol: str,
    *,
    entry_name: str = "",
    channel: int | None = None,
    writable: bool = False,
) -> PvRequest:
    """The request of a symbol's value under the controller `path` (a
    terminal's: the value goes under its channel, when it has one)."""
    if channel is not None:
        path = (*path, channel_node(channel))
    names = value_names(_symbol_name(path, symbol), entry_name, channel)
    return PvRequest(path, symbol, names, writable)


def point_request(path: tuple[Node, ...], point: Point) -> PvRequest:
    """The request of a point of the terminal at `path`."""
    return symbol_request(
        path,
        point.symbol,
        entry_name=point.entry_name,
        channel=point.channel,
        writable=point.writable,
    )


def twin_request(request: PvRequest, leaf: str, suffix: str) -> PvRequest:
    """The request of a read-only attribute served beside `request`'s (a
    scaled value's raw count): same place, each readable name + `suffix`."""
    return PvRequest(request.path, leaf, tuple(name + suffix for name in request.names))


def coe_leaf(attribute: str) -> str:
    """A CoE attribute's leaf: `Coe <attribute>` (-> `CoeFilterSettings`)."""
    return COE_LEAF_PREFIX + attribute


def coe_request(path: tuple[Node, ...], leaf: str, coe: CoePoint) -> PvRequest:
    """The request of a CoE value of the terminal at `path`: under its object,
    named by its sub-item (then with its sub-index, if two share a name)."""
    names = (coe.name, f"{coe.name} {coe.subindex:02X}") if coe.name else ()
    return PvRequest((*path, coe_node(coe.index)), leaf, names, coe.writable)


@lru_cache(maxsize=65536)
def value_names(symbol: str, entry_name: str, channel: int | None) -> tuple[str, ...]:
    """Readable names of a value, shortest first: its entry without a leading
    group (`Underrange`), its entry (`Status.Underrange`), its symbol; each
    without the channel's own words (`Channel 1`, `Ch1`).

    Cached: every terminal of a type repeats the same points."""
    wanted: list[str] = []
    if entry_name:
        first, dot, rest = entry_name.partition(".")
        if dot and first.strip().lower() in GROUP_WORDS:
            wanted.append(rest)
        wanted.append(entry_name)
    wanted.append(symbol)
    plain = [_without_channel(name, channel) for name in wanted]
    names = tuple(dict.fromkeys(name for name in plain if default_segment(name)))
    return names or (symbol,)


@lru_cache(maxsize=65536)
def default_segment(name: str, kind: NodeKind | None = None) -> str:
    """The readable PascalCase segment of a name (kind None: a value).

    Cached: every terminal of a type repeats the same symbol names."""
    if kind is NodeKind.CHANNEL:
        return f"CH{int(name)}"
    if kind is NodeKind.COE_OBJECT:
        return f"C{name}"
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

    Raises `UserError` for a prefix or an alias that cannot fit or that equals
    another name; everything else is made to fit and reported in
    `PvNames.shortened`.
    """
    check_prefix(prefix)
    aliases = dict(aliases or {})
    for key, segment in aliases.items():
        check_alias(key, segment)
    used: set[str] = set()
    shortened: list[Shortening] = []
    controllers: dict[tuple[Node, ...], str] = {}
    leaves: dict[PvRequest, str] = {}
    children: dict[tuple[Node, ...], set[Node | PvRequest]] = defaultdict(set)
    for request in requests:  # order-free: siblings are sorted when named
        children[request.path].add(request)
    for path in list(children):  # each controller once, however many leaves
        for depth in range(len(path)):
            children[path[:depth]].add(path[depth])
    budgets = _budgets(path[-1] for path in children if path)

    def name_children(parent: tuple[Node, ...], segments: tuple[str, ...]) -> None:
        level = _Level.of(prefix, parent, segments, budgets)
        wanted = [
            _wanted(level, child, aliases)
            for child in sorted(children[parent], key=_child_sort_key)
        ]
        used.update(item.key for item in wanted if item.pinned is not None)
        resolved = _resolve_siblings(parent, wanted, shortened)
        for item, segment in zip(wanted, resolved, strict=True):
            if isinstance(item.child, Node):
                path = (*parent, item.child)
                controllers[path] = segment
                name_children(path, (*segments, segment))
            else:
                leaves[item.child] = segment

    name_children((), ())
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
    if prefix.endswith(":"):
        raise UserError(
            f"PV prefix {prefix!r} must not end in ':' (the IOC adds the ':' "
            "before the master's name)",
            where="prefix",
        )
    if len(prefix) > MAX_PREFIX_LENGTH:
        raise UserError(
            f"PV prefix {prefix!r} is {len(prefix)} characters; at most"
            f" {MAX_PREFIX_LENGTH} leave room for master, coupler, terminal,"
            f" channel and value within {MAX_PV_LENGTH} characters",
            where="prefix",
        )


def check_alias(key: str, segment: str) -> None:
    """An alias must be a segment FastCS, PVI and .bob screens all take as is."""
    if not _SEGMENT_RE.match(segment):
        raise UserError(
            f"alias {segment!r} must be PascalCase: an upper-case letter, then"
            " letters and digits only (EPICS, PVI and .bob screens all need that)",
            where=f"pv_aliases[{key!r}]",
        )


@dataclass(slots=True)
class _Wanted:
    child: Node | PvRequest
    key: str
    names: tuple[str, ...]
    """Readable segments to try, shortest first."""
    pinned: str | None
    """The alias' segment."""
    fixed: bool
    """A channel or CoE object: its segment is what it is."""
    cap: int
    hash_source: str


@dataclass(frozen=True)
class _Level:
    """What the children of one controller share: where they sit and their room."""

    twincat: tuple[str, ...]
    """The TwinCAT names along the path: where the children's alias keys start."""
    terminal: str | None
    """The last of them: a value's symbol is named without it (`_symbol_name`)."""
    pv: str
    """The controller's PV name: the prefix and the segments down to it."""
    leaf_caps: tuple[int, int]
    """Room for a value's name below it: read-only, writable (its `_RBV`
    twin's 4 characters kept free)."""
    budgets: Budgets

    @classmethod
    def of(
        cls,
        prefix: str,
        path: tuple[Node, ...],
        segments: tuple[str, ...],
        budgets: Budgets,
    ) -> _Level:
        room = _leaf_cap(prefix, path, segments, budgets)
        twincat = tuple(node.name for node in path if node.kind in TWINCAT_KINDS)
        return cls(
            twincat,
            twincat[-1] if twincat else None,
            ":".join((prefix, *segments)),
            (room, room - len(RBV_SUFFIX)),
            budgets,
        )


def _wanted(
    level: _Level, child: Node | PvRequest, aliases: Mapping[str, str]
) -> _Wanted:
    """What one child of `level` wants to be called, and its room."""
    if isinstance(child, Node):
        segment = default_segment(child.name, child.kind)
        if child.kind not in TWINCAT_KINDS:
            key = alias_key([*level.twincat, segment])
            return _Wanted(child, key, (segment,), None, True, len(segment), "")
        key = alias_key([*level.twincat, child.name])
        cap = _controller_cap(child.kind, level.pv, level.budgets)
        source = f"{child.kind}:{child.name}"
        names: tuple[str, ...] = (segment,)
        writable = False
    else:
        relative = _relative_name(level.terminal, child.leaf)
        key = alias_key([*level.twincat, relative])
        cap = level.leaf_caps[child.writable]
        source = f"leaf:{child.leaf}"
        names = tuple(dict.fromkeys(default_segment(n) for n in child.names or ()))
        names = tuple(n for n in names if n) or (default_segment(relative),)
        writable = child.writable
    pinned = aliases.get(key)
    if pinned is not None and len(pinned) > cap:
        room = f"{MAX_BASE_LENGTH if writable else MAX_PV_LENGTH} characters"
        raise UserError(
            f"alias {pinned!r} makes a PV longer than {room}"
            f"{f' (+ {RBV_SUFFIX})' if writable else ''}; at most {cap} fit here",
            where=f"pv_aliases[{key!r}]",
        )
    return _Wanted(child, key, names, pinned, False, cap, source)


def _child_sort_key(
    child: Node | PvRequest,
) -> tuple[str, str, tuple[str, ...], bool]:
    if isinstance(child, Node):
        return (child.kind, child.name, (), False)
    return ("~leaf", child.leaf, child.names, child.writable)


def _symbol_name(path: tuple[Node, ...], leaf: str) -> str:
    """A symbol named `<terminal>.<rest>` is named by `<rest>` under its terminal."""
    twincat = [node.name for node in path if node.kind in TWINCAT_KINDS]
    return _relative_name(twincat[-1] if twincat else None, leaf)


def _relative_name(terminal: str | None, leaf: str) -> str:
    """`leaf` without `<terminal>.` in front (`_symbol_name`)."""
    if terminal is not None and leaf.startswith(terminal + "."):
        return leaf[len(terminal) + 1 :]
    return leaf


def _without_channel(name: str, channel: int | None) -> str:
    """`AI Standard Channel 1.Value` -> `AI Standard .Value` (channel 1)."""
    if channel is None:
        return name
    return re.sub(rf"(?i)\b(?:channel|chn?)\s*\.?\s*{channel}\b", " ", name)


def _budgets(nodes: Iterable[Node]) -> dict[NodeKind, int]:
    """Each level's budget: its longest standard segment, at least `MIN_BUDGET`."""
    budgets = dict(MIN_BUDGET)
    for node in nodes:
        segment = default_segment(node.name, node.kind)
        if _STANDARD_SEGMENT.match(segment):
            budgets[node.kind] = max(budgets[node.kind], len(segment))
    return budgets


def _leaf_cap(
    prefix: str, parent: tuple[Node, ...], segments: tuple[str, ...], budgets: Budgets
) -> int:
    """Longest name a read-only value under `parent` may take: what the
    prefix and the budgets of the levels down to it leave (all of them,
    present or not; a level longer than its budget counts as it is). Where a
    terminal sits never changes it."""
    actual = {
        node.kind: len(segment) for node, segment in zip(parent, segments, strict=True)
    }
    levels = _LEVELS[parent[-1].kind] if parent else ()
    used = sum(1 + max(budgets[level], actual.get(level, 0)) for level in levels)
    return MAX_PV_LENGTH - len(prefix) - used - 1


def _controller_cap(kind: NodeKind, parent_pv: str, budgets: Budgets) -> int:
    """Longest segment a master, coupler or terminal may take: the budgets of
    the levels below it and `MIN_LEAF` (+ `_RBV`) stay free."""
    below = _path_budget(NodeKind.COE_OBJECT, budgets) - _path_budget(kind, budgets)
    room = MAX_BASE_LENGTH - len(parent_pv) - 1 - below - (1 + MIN_LEAF)
    return min(room, MAX_CONTROLLER_SEGMENT)


def _resolve_siblings(
    parent: tuple[Node, ...], wanted: list[_Wanted], shortened: list[Shortening]
) -> list[str]:
    """Fit every sibling into its room and make all siblings distinct
    (without case): a generated name moves to its next readable name, then
    gets a hash; an alias never moves, it must differ from every other name.

    Returns the segment of each entry of `wanted`, by position."""
    readable = _readable_choice(wanted)
    chosen = dict(readable)
    reasons: dict[int, str] = {}
    hashed: set[int] = set()
    for index, item in enumerate(wanted):
        if item.pinned is None and not item.fixed:
            fitted = fit(readable[index], item.cap, item.hash_source)
            chosen[index] = fitted.segment
            if fitted.reason:
                reasons[index] = fitted.reason
            if fitted.hashed:
                hashed.add(index)
    clashing = _clashing(wanted, chosen)
    for length in HASH_LENGTHS:
        if not clashing:
            break
        for index in clashing:
            item = wanted[index]
            if item.cap >= length + 2:
                base = drop_inner_vowels(readable[index], item.cap)
                chosen[index] = with_hash(base, item.cap, item.hash_source, length)
                reasons[index] = "made distinct from a sibling with the same name"
                hashed.add(index)
        clashing = _clashing(wanted, chosen)
    for index in clashing:
        item = wanted[index]
        taken = {s.lower() for i, s in chosen.items() if i != index}
        base = drop_inner_vowels(readable[index], item.cap)
        chosen[index] = numbered(base, item.cap, taken | RESERVED_SEGMENTS)
        reasons[index] = "numbered apart from a sibling with the same name"
        hashed.add(index)
    _check_pinned(wanted, chosen)
    for index, item in enumerate(wanted):
        if index in reasons:
            shortened.append(
                Shortening(
                    item.key,
                    readable[index],
                    chosen[index],
                    reasons[index],
                    hashed=index in hashed,
                    node=(*parent, item.child)
                    if isinstance(item.child, Node)
                    else item.child,
                )
            )
    return [chosen[index] for index in range(len(wanted))]


def _readable_choice(wanted: list[_Wanted]) -> dict[int, str]:
    """Each sibling's shortest readable name that no other sibling takes: a
    generated name clashing with another (or with a channel, a CoE object, a
    reserved name) moves on to its next one while it has one."""
    level = [0] * len(wanted)
    while True:
        chosen = {
            index: item.pinned or item.names[level[index]]
            for index, item in enumerate(wanted)
        }
        groups: dict[str, list[int]] = defaultdict(list)
        for index, item in enumerate(wanted):
            if item.pinned is None:  # aliases are checked against the outcome
                groups[chosen[index].lower()].append(index)
        moving = [
            index
            for lower, members in groups.items()
            if len(members) > 1 or lower in RESERVED_SEGMENTS
            for index in members
            if not wanted[index].fixed and level[index] + 1 < len(wanted[index].names)
        ]
        if not moving:
            return chosen
        for index in moving:
            level[index] += 1


def _clashing(wanted: list[_Wanted], chosen: dict[int, str]) -> list[int]:
    """Positions of generated siblings whose segment is not unique (without
    case) or is reserved; channels, CoE objects and aliases never move."""
    groups: dict[str, list[int]] = defaultdict(list)
    for index in chosen:
        groups[chosen[index].lower()].append(index)
    return sorted(
        index
        for lower, members in groups.items()
        for index in members
        if wanted[index].pinned is None
        and not wanted[index].fixed
        and (
            len([m for m in members if wanted[m].pinned is None]) > 1
            or lower in RESERVED_SEGMENTS
        )
    )


def _check_pinned(wanted: list[_Wanted], chosen: dict[int, str]) -> None:
    """An alias must differ from every sibling's name and from FastCS's own."""
    for index, item in enumerate(wanted):
        if item.pinned is None:
            continue
        lower = item.pinned.lower()
        if lower in RESERVED_SEGMENTS:
            raise UserError(
                f"alias {item.pinned!r} is the name of FastCS's own PVI record"
                " of every controller: choose another",
                where=f"pv_aliases[{item.key!r}]",
            )
        for other_index, other in enumerate(wanted):
            if other_index == index or chosen[other_index].lower() != lower:
                continue
            what = "the alias of" if other.pinned is not None else "the name of"
            raise UserError(
                f"alias {item.pinned!r} is also {what} {other.key!r}"
                f" ({chosen[other_index]}): choose another",
                where=f"pv_aliases[{item.key!r}]",
            )


def _words_of(text: str) -> list[str]:
    for special, replacement in _SPECIAL_CHARACTERS.items():
        text = text.replace(special, replacement)
    ascii_text = (
        unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    )
    words: list[str] = _WORD_RE.findall(ascii_text)
    return [_ABBREVIATIONS.get(word.lower(), word) for word in words]
