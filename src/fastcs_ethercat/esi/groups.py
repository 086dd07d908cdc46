"""PDO groups: the mutually exclusive PDO configurations a device offers.

Two sources, in this order:

1. `Info/VendorSpecific/TwinCAT/AlternativeSmMapping` (TwinCAT's list of
   predefined PDO assignments), used when it offers a choice (two or more
   mappings with an `<Sm>`): one group per mapping with its name and its PDOs
   per Sm; `Default="1"` marks the default. When no mapping is marked, the
   default is the one whose PDOs are exactly those with an `Sm` attribute
   (TwinCAT's assignment when nobody chooses), if any.

2. Otherwise the `<Exclude>` graph of the PDOs (EL1502 up to #x00140000,
   EP3174-0002, EP4374-0002). Rule:
   - make the graph symmetric (A excludes B means B excludes A) and split it
     into connected components;
   - the alternatives of a component are its maximal sets of PDOs that do
     not exclude each other (maximal independent sets): EL1502 Tx gives
     {CNT Inputs Channel 1, CNT Inputs Channel 2} and {CNT Inputs};
   - alternatives that give channels of one direction different PDO formats
     (channel 1 Standard + channel 2 Compact) are dropped when uniform ones
     remain: valid in TwinCAT, but never what a vendor predefines (EL31x2);
   - in every component the default alternative comes first: the one with
     the most PDOs that carry an `Sm` attribute (TwinCAT's default
     assignment); the others follow in file order;
   - group k = the k-th alternative of every component (a component with
     fewer alternatives contributes its default) plus the PDOs outside the
     graph that carry an `Sm` attribute (always assigned). Group 0 is the
     default. A PDO without `Sm` goes to the Sm its direction uses.
   On the shared files this reproduces the PDO sets of the vendor's mappings
   for 45 of the 62 devices that have both (EL3104, EL1502, EL31x2, ...);
   the rest (EL1252, EL2212, EL3773, ELM3704) predefine a curated subset of
   what their Exclude graph allows.
   Names: "Per-Channel"/"Combined" when one of two groups is all per-channel
   PDOs and the other has none; otherwise the words of the PDO names only
   that group uses ("Standard", "Compact"); a nameless default is
   "Standard" (or "Default" if taken), other nameless or clashing groups
   are "Alternative N".

A PDO several groups share belongs to each of them. Devices without
alternatives have no groups.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from .model import EsiPdo, EsiPdoGroup, EsiSyncManager, parse_esi_int
from .xmltext import Element, bool_attr, fail, int_attr, int_of, text_of

MAX_ALTERNATIVES = 256
"""Cap on the alternatives enumerated per exclusion component."""


def parse_alternative_mappings(
    twincat: Element, known: dict[int, EsiPdo]
) -> tuple[EsiPdoGroup, ...]:
    """Groups from the `AlternativeSmMapping`s of a `VendorSpecific/TwinCAT`.

    Real-file leniency: a mapping without any `<Sm>` (EL3632) is ignored; one
    without a name is named after its first operation mode, else "Mapping N";
    empty `<Pdo/>`s (EL2258) are skipped; PDOs the device does not define
    (EL2014 "Compact Diagnostics") are left out and listed in
    `unknown_pdo_indices`.
    """
    groups: list[EsiPdoGroup] = []
    for number, mapping in enumerate(twincat.iterfind("AlternativeSmMapping"), 1):
        group = _parse_mapping(mapping, known, number)
        if group is not None:
            groups.append(group)
    return _settle_default(_unique_names(groups), known)


def _parse_mapping(
    mapping: Element, known: dict[int, EsiPdo], number: int
) -> EsiPdoGroup | None:
    name = ""
    sm_pdos: dict[int, tuple[int, ...]] = {}
    channels: dict[int, int] = {}
    modes: list[str] = []
    ordered: list[int] = []
    unknown: list[int] = []
    for child in mapping:
        tag = child.tag
        if tag == "Name":
            if not name:
                name = text_of(child)
        elif tag == "Sm":
            sm = int_attr(child, "No")
            if sm is None:
                raise fail(child, "AlternativeSmMapping <Sm> has no No attribute")
            indices: list[int] = []
            for pdo in child.iterfind("Pdo"):
                if not text_of(pdo):
                    continue
                index = int_of(pdo, "AlternativeSmMapping Pdo")
                if index not in known:
                    unknown.append(index)
                    continue
                indices.append(index)
                channel = pdo.get("ChannelNo")
                if channel is not None and channel.strip().isdigit():
                    channels[index] = int(channel)
            sm_pdos[sm] = sm_pdos.get(sm, ()) + tuple(indices)
            ordered.extend(i for i in indices if i not in ordered)
        elif tag == "OperationMode":
            mode_name = child.findtext("Name")
            if mode_name and mode_name.strip():
                modes.append(mode_name.strip())
    if not sm_pdos:
        return None
    return EsiPdoGroup(
        name=name or (modes[0] if modes else f"Mapping {number}"),
        is_default=bool_attr(mapping, "Default"),
        pdo_indices=tuple(ordered),
        sm_pdos=sm_pdos,
        origin="alternative_sm_mapping",
        pdo_channels=channels,
        operation_modes=tuple(modes),
        unknown_pdo_indices=tuple(unknown),
    )


def _unique_names(groups: list[EsiPdoGroup]) -> list[EsiPdoGroup]:
    """Suffix " (2)", " (3)" to repeated names so a name selects one group."""
    seen: dict[str, int] = {}
    result = []
    for group in groups:
        count = seen.get(group.name, 0) + 1
        seen[group.name] = count
        result.append(
            group if count == 1 else replace(group, name=f"{group.name} ({count})")
        )
    return result


def _settle_default(
    groups: list[EsiPdoGroup], known: dict[int, EsiPdo]
) -> tuple[EsiPdoGroup, ...]:
    """Exactly one default: the first marked, else the Sm-attribute match."""
    marked = [i for i, group in enumerate(groups) if group.is_default]
    if marked:
        chosen: int | None = marked[0]
    else:
        assigned = {index for index, pdo in known.items() if pdo.sm is not None}
        chosen = next(
            (i for i, g in enumerate(groups) if set(g.pdo_indices) == assigned), None
        )
    return tuple(
        group
        if group.is_default == (i == chosen)
        else replace(group, is_default=i == chosen)
        for i, group in enumerate(groups)
    )


def _components(
    adjacency: dict[int, set[int]], order: dict[int, int]
) -> list[list[int]]:
    seen: set[int] = set()
    components: list[list[int]] = []
    for start in sorted(adjacency, key=order.__getitem__):
        if start in seen:
            continue
        stack, members = [start], set[int]()
        while stack:
            node = stack.pop()
            if node not in members:
                members.add(node)
                stack.extend(adjacency[node] - members)
        seen |= members
        components.append(sorted(members, key=order.__getitem__))
    return components


def _maximal_independent_sets(
    members: list[int], adjacency: dict[int, set[int]]
) -> list[list[int]] | None:
    """Maximal sets without an exclusion inside (Bron-Kerbosch on bitsets).

    None when there are more than MAX_ALTERNATIVES of them.
    """
    bit = {node: 1 << i for i, node in enumerate(members)}
    full = (1 << len(members)) - 1
    compatible = []
    for node in members:
        excluded = sum(bit[other] for other in adjacency[node] if other in bit)
        compatible.append(full & ~excluded & ~bit[node])
    found: list[int] = []
    if not _expand(0, full, 0, compatible, found):
        return None
    return [[node for i, node in enumerate(members) if mask >> i & 1] for mask in found]


def _expand(
    chosen: int, candidates: int, done: int, compatible: list[int], found: list[int]
) -> bool:
    """One Bron-Kerbosch step (with pivot): maximal sets extending `chosen`
    go to `found`; False once there are too many. (A module function, not a
    closure: a closure that calls itself is a reference cycle, garbage only
    the collector frees.)"""
    if not candidates and not done:
        found.append(chosen)
        return len(found) <= MAX_ALTERNATIVES
    pivot_pool = candidates | done
    pivot = (pivot_pool & -pivot_pool).bit_length() - 1
    rest = candidates & ~compatible[pivot]
    while rest:
        low = rest & -rest
        position = low.bit_length() - 1
        if not _expand(
            chosen | low,
            candidates & compatible[position],
            done & compatible[position],
            compatible,
            found,
        ):
            return False
        candidates &= ~low
        done |= low
        rest &= ~low
    return True


def _is_mixed(alternative: list[int], by_index: dict[int, EsiPdo]) -> bool:
    """True when channels of one direction use different PDO formats."""
    templates: dict[str, set[str]] = {}
    for index in alternative:
        pdo = by_index[index]
        if pdo.channel_template is not None:
            templates.setdefault(pdo.direction, set()).add(pdo.channel_template)
    return any(len(found) > 1 for found in templates.values())


def _drop_mixed(
    alternatives: list[list[int]], by_index: dict[int, EsiPdo]
) -> list[list[int]]:
    """Keep alternatives where every channel uses the same PDO format.

    Mixing formats per channel (channel 1 "AI Standard", channel 2 "AI
    Compact" in one component) is valid for TwinCAT but is never what a
    vendor offers as a predefined assignment (EL31x2: Legacy, Legacy Compact,
    Standard, Compact), and it multiplies groups.
    """
    uniform = [alt for alt in alternatives if not _is_mixed(alt, by_index)]
    return uniform if len(uniform) > 1 else alternatives


def groups_from_excludes(
    pdos: Sequence[EsiPdo], sync_managers: Sequence[EsiSyncManager]
) -> tuple[EsiPdoGroup, ...]:
    """Groups derived from `<Exclude>` (see the module docstring for the rule)."""
    order = {pdo.index: position for position, pdo in enumerate(pdos)}
    adjacency: dict[int, set[int]] = {}
    for pdo in pdos:
        for other in pdo.excludes:
            if other in order and other != pdo.index:
                adjacency.setdefault(pdo.index, set()).add(other)
                adjacency.setdefault(other, set()).add(pdo.index)
    if not adjacency:
        return ()
    by_index = {pdo.index: pdo for pdo in pdos}
    per_component: list[list[list[int]]] = []
    for members in _components(adjacency, order):
        alternatives = _maximal_independent_sets(members, adjacency)
        if alternatives is None:
            alternatives = [[member] for member in members]
        alternatives = _drop_mixed(alternatives, by_index)
        alternatives.sort(key=lambda alt: [order[i] for i in alt])
        default = max(
            alternatives,
            key=lambda alt: sum(by_index[i].sm is not None for i in alt),
        )
        alternatives.remove(default)
        per_component.append([default, *alternatives])
    always = [
        pdo.index for pdo in pdos if pdo.index not in adjacency and pdo.sm is not None
    ]
    count = max(len(alternatives) for alternatives in per_component)
    member_sets: list[list[int]] = []
    for rank in range(count):
        chosen = set(always)
        for alternatives in per_component:
            chosen.update(alternatives[rank if rank < len(alternatives) else 0])
        member_sets.append(sorted(chosen, key=order.__getitem__))
    names = name_groups(member_sets, by_index)
    default_sm = _default_sms(pdos, sync_managers)
    groups = []
    for rank, members in enumerate(member_sets):
        sm_pdos: dict[int, tuple[int, ...]] = {}
        for index in members:
            pdo = by_index[index]
            sm = pdo.sm if pdo.sm is not None else default_sm[pdo.direction]
            sm_pdos[sm] = (*sm_pdos.get(sm, ()), index)
        groups.append(
            EsiPdoGroup(
                name=names[rank],
                is_default=rank == 0,
                pdo_indices=tuple(members),
                sm_pdos=dict(sorted(sm_pdos.items())),
                origin="exclude",
            )
        )
    return tuple(groups)


def _default_sms(
    pdos: Sequence[EsiPdo], sync_managers: Sequence[EsiSyncManager]
) -> dict[str, int]:
    """Sm a PDO without an Sm attribute would go to, per direction."""
    result = {"tx": 3, "rx": 2}
    for direction, kind in (("tx", "Inputs"), ("rx", "Outputs")):
        used = [p.sm for p in pdos if p.direction == direction and p.sm is not None]
        if used:
            result[direction] = max(set(used), key=used.count)
            continue
        for sm in sync_managers:
            if sm.kind == kind:
                result[direction] = sm.number
                break
    return result


def name_groups(member_sets: list[list[int]], by_index: dict[int, EsiPdo]) -> list[str]:
    """Readable, distinct names for exclusion-derived groups (default first)."""
    common = set.intersection(*(set(members) for members in member_sets))
    varying = [[i for i in members if i not in common] for members in member_sets]
    if len(varying) == 2:
        per_channel = [
            bool(v) and all(by_index[i].channel is not None for i in v) for v in varying
        ]
        combined = [
            bool(v) and all(by_index[i].channel is None for i in v) for v in varying
        ]
        if per_channel[0] and combined[1]:
            return ["Per-Channel", "Combined"]
        if combined[0] and per_channel[1]:
            return ["Combined", "Per-Channel"]
    words: list[list[str]] = []
    for members in varying:
        seen: list[str] = []
        for index in members:
            pdo = by_index[index]
            label = (pdo.channel_template or pdo.name).replace("{channel}", " ")
            for word in label.split():
                if word not in seen:
                    seen.append(word)
        words.append(seen)
    names: list[str] = []
    for position, own in enumerate(words):
        others = {w for i, ws in enumerate(words) if i != position for w in ws}
        names.append(" ".join(w for w in own if w not in others))
    return _fill_missing_names(names)


def _fill_missing_names(names: list[str]) -> list[str]:
    """Empty or repeated names: "Standard"/"Default" for the default group
    (group 0), "Alternative N" for the others."""
    result: list[str] = []
    for position, name in enumerate(names):
        clash = not name or names.count(name) > 1
        if clash and position == 0:
            name = "Standard" if "Standard" not in names else "Default"
        elif clash:
            name = f"Alternative {position}"
        result.append(name)
    return result


def derive_groups(
    twincat: Element | None,
    pdos: Sequence[EsiPdo],
    sync_managers: Sequence[EsiSyncManager],
) -> tuple[EsiPdoGroup, ...]:
    """AlternativeSmMapping groups when they offer a choice, else Exclude groups.

    A single mapping is no choice (EP3184-0002 rev 0x00110002 has one unnamed
    mapping next to a Standard/Compact Exclude graph): the Exclude graph then
    decides, and without one the device has no groups.
    """
    if twincat is not None:
        groups = parse_alternative_mappings(twincat, {pdo.index: pdo for pdo in pdos})
        if len(groups) > 1:
            return groups
    return groups_from_excludes(pdos, sync_managers)


def has_alternatives(device: Element) -> bool:
    """Cheap check (for the catalog) that `derive_groups` will find groups.

    Mirrors its rules without building PDOs: two or more mappings with an
    `<Sm>`, else an `<Exclude>` naming another PDO the device defines.
    """
    mappings = device.iterfind("Info/VendorSpecific/TwinCAT/AlternativeSmMapping")
    if sum(1 for mapping in mappings if mapping.find("Sm") is not None) > 1:
        return True
    defined: set[int] = set()
    excludes: list[tuple[int, int]] = []
    for pdo in device:
        if pdo.tag not in ("TxPdo", "RxPdo"):
            continue
        own: int | None = None
        targets: list[int] = []
        for child in pdo:
            if child.tag == "Index" or child.tag == "Exclude":
                try:
                    value = parse_esi_int(child.text or "")
                except ValueError:
                    continue
                if child.tag == "Index":
                    own = value
                else:
                    targets.append(value)
        if own is not None:
            defined.add(own)
            excludes.extend((own, target) for target in targets)
    return any(own != target and target in defined for own, target in excludes)
