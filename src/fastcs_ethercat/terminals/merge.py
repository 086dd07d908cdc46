"""Regenerate: new ESI facts, the engineer's old choices, and what changed.

The freshly generated terminal brings the facts (PDOs, types, groups, CoE
dictionary, identity); the old file brings the choices: `selected` flags of
symbols, CoE objects and their sub-indices, `selected_pdo_group`, the
oversampling factor, `fastcs_name`s (renaming an attribute renames PVs) and
a member's engineering-unit and severity overrides (`MEMBER_CHOICES`).
A choice that no longer fits (its group is gone, its symbol moved out of the
selected group) falls back to the generated default and is named in the
report.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

from fastcs_ethercat.terminals.checks import check_terminal
from fastcs_ethercat.terminals.model import (
    MEMBER_CHOICES,
    CoeObject,
    SymbolNode,
    TerminalType,
)
from fastcs_ethercat.terminals.names import expand, take_unique


@dataclass
class ChangeReport:
    """What a regenerate changed in one terminal type (facts and choices)."""

    type_name: str
    identity: list[str] = field(default_factory=list)
    symbols_added: list[str] = field(default_factory=list)
    symbols_removed: list[str] = field(default_factory=list)
    symbols_changed: list[str] = field(default_factory=list)
    groups_added: list[str] = field(default_factory=list)
    groups_removed: list[str] = field(default_factory=list)
    groups_changed: list[str] = field(default_factory=list)
    coe_added: list[str] = field(default_factory=list)
    coe_removed: list[str] = field(default_factory=list)
    coe_changed: list[str] = field(default_factory=list)
    choices: list[str] = field(default_factory=list)
    """Choices of the old file that could not be kept, and why."""

    def lines(self) -> list[str]:
        """One line per change, for the CLI summary."""
        labelled = [
            ("identity", self.identity),
            ("symbol added", self.symbols_added),
            ("symbol removed", self.symbols_removed),
            ("symbol changed", self.symbols_changed),
            ("PDO group added", self.groups_added),
            ("PDO group removed", self.groups_removed),
            ("PDO group changed", self.groups_changed),
            ("CoE object added", self.coe_added),
            ("CoE object removed", self.coe_removed),
            ("CoE object changed", self.coe_changed),
            ("choice not kept", self.choices),
        ]
        return [f"{label}: {item}" for label, items in labelled for item in items]

    def summary(self) -> str:
        """`EL3104: 2 symbols added, ...` or `EL3104: unchanged`."""
        counts = [
            (len(self.identity), "identity change"),
            (len(self.symbols_added), "symbol added"),
            (len(self.symbols_removed), "symbol removed"),
            (len(self.symbols_changed), "symbol changed"),
            (len(self.groups_added) + len(self.groups_removed), "group added/removed"),
            (len(self.groups_changed), "group changed"),
            (len(self.coe_added) + len(self.coe_removed), "CoE object added/removed"),
            (len(self.coe_changed), "CoE object changed"),
            (len(self.choices), "choice not kept"),
        ]
        parts = [f"{count} {label}" for count, label in counts if count]
        return f"{self.type_name}: {', '.join(parts) if parts else 'unchanged'}"


def _symbol_label(node: SymbolNode) -> str:
    if not node.channels:
        return node.name_template
    channels = ",".join(str(c) for c in node.channels)
    return f"{node.name_template} [channels {channels}]"


def _facts(node: SymbolNode) -> dict[str, Any]:
    """A node's ESI facts: everything but the engineer's choices."""
    data = node.model_dump(mode="json", exclude={"selected", "fastcs_name"})
    for member in data["members"]:
        for choice in ("fastcs_name", *MEMBER_CHOICES):
            member.pop(choice)
    return data


_SymbolKey = Callable[[SymbolNode], Hashable]

_MATCH_KEYS: tuple[_SymbolKey, ...] = (
    lambda n: (n.name_template, tuple(n.channels), tuple(n.pdo_indices)),
    lambda n: (n.name_template, tuple(n.channels)),
    lambda n: n.name_template,
)
"""Tried in turn: ESI files name several PDOs alike, PDO indices tell them apart."""


def _match_symbols(old: list[SymbolNode], new: list[SymbolNode]) -> dict[int, int]:
    """new position -> old position, pairing only keys that are unique on both sides."""
    matched: dict[int, int] = {}
    for key in _MATCH_KEYS:
        free_old = [i for i in range(len(old)) if i not in matched.values()]
        free_new = [i for i in range(len(new)) if i not in matched]
        old_keys = Counter(key(old[i]) for i in free_old)
        new_keys = Counter(key(new[i]) for i in free_new)
        by_key = {key(old[i]): i for i in free_old}
        for position in free_new:
            wanted = key(new[position])
            if old_keys[wanted] == 1 and new_keys[wanted] == 1:
                matched[position] = by_key[wanted]
    return matched


def merge_terminal(
    type_name: str, old: TerminalType, new: TerminalType
) -> tuple[TerminalType, ChangeReport]:
    """`new` (freshly generated) carrying `old`'s choices, and the report."""
    merged = new.model_copy(deep=True)
    report = ChangeReport(type_name=type_name)
    _compare_identity(old, new, report)
    matched = _match_symbols(old.symbol_nodes, merged.symbol_nodes)
    _compare_symbols(old, merged, matched, report)
    _compare_groups(old, merged, report)
    _keep_group_choice(old, merged, report)
    _keep_symbol_choices(old, merged, matched, report)
    _keep_oversampling_choice(old, merged, report)
    _merge_coe(old, merged, report)
    check_terminal(type_name, merged)
    return merged, report


def _compare_identity(
    old: TerminalType, new: TerminalType, report: ChangeReport
) -> None:
    for name in ("vendor_id", "product_code", "revision_number"):
        before = getattr(old.identity, name)
        after = getattr(new.identity, name)
        if before != after:
            report.identity.append(f"{name} 0x{before:08x} -> 0x{after:08x}")
    for name in ("description", "group_type", "esi_file"):
        before, after = getattr(old, name), getattr(new, name)
        if before != after:
            report.identity.append(f"{name} {before!r} -> {after!r}")


def _compare_symbols(
    old: TerminalType,
    merged: TerminalType,
    matched: dict[int, int],
    report: ChangeReport,
) -> None:
    for position, node in enumerate(merged.symbol_nodes):
        if position not in matched:
            report.symbols_added.append(_symbol_label(node))
            continue
        before = _facts(old.symbol_nodes[matched[position]])
        after = _facts(node)
        changed = [key for key in after if before.get(key) != after[key]]
        if changed:
            report.symbols_changed.append(
                f"{_symbol_label(node)} ({', '.join(changed)})"
            )
    kept = set(matched.values())
    for position, node in enumerate(old.symbol_nodes):
        if position not in kept:
            report.symbols_removed.append(_symbol_label(node))


def _group_symbols(terminal: TerminalType, indices: list[int]) -> set[str]:
    return {
        name
        for index in indices
        if index < len(terminal.symbol_nodes)
        for name in terminal.symbol_nodes[index].names()
    }


def _compare_groups(
    old: TerminalType, merged: TerminalType, report: ChangeReport
) -> None:
    old_groups = {g.name: g for g in old.pdo_groups}
    new_groups = {g.name: g for g in merged.pdo_groups}
    report.groups_added += [name for name in new_groups if name not in old_groups]
    report.groups_removed += [name for name in old_groups if name not in new_groups]
    for name, group in new_groups.items():
        before = old_groups.get(name)
        if before is None:
            continue
        what = []
        if before.pdo_indices != group.pdo_indices:
            what.append("pdo_indices")
        if _group_symbols(old, before.symbol_indices) != _group_symbols(
            merged, group.symbol_indices
        ):
            what.append("symbols")
        if before.is_default != group.is_default:
            what.append("is_default")
        if before.oversampling_factor != group.oversampling_factor:
            what.append("oversampling_factor")
        if what:
            report.groups_changed.append(f"{name} ({', '.join(what)})")


def _keep_group_choice(
    old: TerminalType, merged: TerminalType, report: ChangeReport
) -> None:
    wanted = old.selected_pdo_group
    if wanted is None or wanted == merged.selected_pdo_group:
        return
    names = [g.name for g in merged.pdo_groups]
    if wanted in names:
        merged.selected_pdo_group = wanted
    else:
        report.choices.append(
            f"selected_pdo_group {wanted!r} no longer exists; "
            f"now {merged.selected_pdo_group!r}"
        )


def _keep_symbol_choices(
    old: TerminalType,
    merged: TerminalType,
    matched: dict[int, int],
    report: ChangeReport,
) -> None:
    taken = {
        expand(node.fastcs_name, channel)
        for position, node in enumerate(merged.symbol_nodes)
        if position not in matched
        for _, channel in node.channel_positions()
    }
    for position, node in enumerate(merged.symbol_nodes):
        groups = merged.groups_of(position)
        if position not in matched:
            if groups:
                node.selected = merged.selected_pdo_group in groups
            continue
        before = old.symbol_nodes[matched[position]]
        node.selected = before.selected
        if node.selected and not merged.selectable(position):
            node.selected = False
            report.choices.append(
                f"{_symbol_label(node)} deselected: not in PDO group "
                f"{merged.selected_pdo_group!r}"
            )
        elif not before.selected and merged.selected_pdo_group in groups:
            old_groups = old.groups_of(matched[position])
            if old_groups and old.selected_pdo_group not in old_groups:
                node.selected = True  # it was off only for being in another group
        _keep_fastcs_name(node, before, taken, report)
        _keep_member_choices(node, before, report)


def _keep_member_choices(
    node: SymbolNode, before: SymbolNode, report: ChangeReport
) -> None:
    """Members keep their fastcs_name and overrides, matched by ESI name."""
    old_members = {m.name: m for m in before.members}
    member_names = {m.fastcs_name for m in node.members}
    for member in node.members:
        old = old_members.pop(member.name, None)
        if old is None:
            continue
        for choice in MEMBER_CHOICES:
            setattr(member, choice, getattr(old, choice))
        wanted = old.fastcs_name
        if wanted != member.fastcs_name and wanted not in member_names:
            member_names.discard(member.fastcs_name)
            member.fastcs_name = wanted
            member_names.add(wanted)
    for old in old_members.values():
        kept = [c for c in MEMBER_CHOICES if getattr(old, c) is not None]
        if kept:
            report.choices.append(
                f"{_symbol_label(node)} member {old.name!r} is gone, with its "
                f"{', '.join(kept)}"
            )


def _keep_fastcs_name(
    node: SymbolNode, before: SymbolNode, taken: set[str], report: ChangeReport
) -> None:
    def expansions(template: str) -> set[str]:
        return {expand(template, ch) for _, ch in node.channel_positions()}

    if not expansions(before.fastcs_name) & taken:
        node.fastcs_name = before.fastcs_name
    else:
        generated = node.fastcs_name
        number = 2
        while expansions(node.fastcs_name) & taken:
            node.fastcs_name = f"{generated}_{number}"
            number += 1
        report.choices.append(
            f"{_symbol_label(node)} fastcs_name {before.fastcs_name!r} clashes; "
            f"now {node.fastcs_name!r}"
        )
    taken.update(expansions(node.fastcs_name))


def _keep_oversampling_choice(
    old: TerminalType, merged: TerminalType, report: ChangeReport
) -> None:
    over = merged.oversampling
    if over is None:
        return
    group = merged.active_group
    if over.by_group and group is not None and group.oversampling_factor is not None:
        over.selected_factor = group.oversampling_factor
        return
    if old.oversampling is None:
        return
    wanted = old.oversampling.selected_factor
    if wanted in over.factors:
        over.selected_factor = wanted
    else:
        report.choices.append(
            f"oversampling factor {wanted} is no longer offered; "
            f"now {over.selected_factor}"
        )


def _coe_facts(obj: CoeObject) -> dict[str, Any]:
    """What the ESI says of an object: not the choices (flags, names)."""
    data = obj.model_dump(mode="json", exclude={"selected", "fastcs_name"})
    for sub in data["sub_items"]:
        sub.pop("fastcs_name")
        sub.pop("selected")
    return data


def _merge_coe(old: TerminalType, merged: TerminalType, report: ChangeReport) -> None:
    old_by_index = {o.index: o for o in old.coe_objects}
    new_indices = {o.index for o in merged.coe_objects}
    taken = {o.fastcs_name for o in merged.coe_objects if o.index not in old_by_index}
    for obj in merged.coe_objects:
        before = old_by_index.get(obj.index)
        label = f"0x{obj.index:04x} {obj.name}"
        if before is None:
            report.coe_added.append(label)
            continue
        old_facts, new_facts = _coe_facts(before), _coe_facts(obj)
        changed = [key for key in new_facts if old_facts.get(key) != new_facts[key]]
        if changed:
            report.coe_changed.append(f"{label} ({', '.join(changed)})")
        obj.selected = before.selected
        if before.fastcs_name not in taken:
            obj.fastcs_name = before.fastcs_name
            taken.add(obj.fastcs_name)
        else:
            obj.fastcs_name = take_unique(obj.fastcs_name, taken, "new")
            report.choices.append(
                f"{label} fastcs_name {before.fastcs_name!r} clashes; "
                f"now {obj.fastcs_name!r}"
            )
        old_subs = {s.subindex: s.fastcs_name for s in before.sub_items}
        old_flags = {s.subindex: s.selected for s in before.sub_items}
        sub_names = {s.fastcs_name for s in obj.sub_items}
        for sub in obj.sub_items:
            sub.selected = old_flags.get(sub.subindex, True)
            wanted = old_subs.get(sub.subindex)
            if wanted and wanted != sub.fastcs_name and wanted not in sub_names:
                sub_names.discard(sub.fastcs_name)
                sub.fastcs_name = wanted
                sub_names.add(wanted)
    for index, before in old_by_index.items():
        if index not in new_indices:
            label = f"0x{index:04x} {before.name}"
            report.coe_removed.append(
                label + (" (was selected)" if before.selected else "")
            )
