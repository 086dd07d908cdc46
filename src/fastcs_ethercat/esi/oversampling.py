"""Oversampling facts, derived from what the real files contain.

Two shapes exist in the shared files:

- EL3702, EL4732 (and other EL37xx/EL47xx): the sample PDO is a template
  with `OSFac`/`OSMin`/`OSMax`/`OSIndexInc` attributes; the factors TwinCAT
  offers are the `OSFac`s of the PDOs in the DC op modes (`Dc/OpMode/Sm/Pdo
  OSFac="n"`), and `VendorSpecific/TwinCAT/Oversampling DefaultFactor` of an
  op mode gives the default factor.
- ELM3704-0000: one fixed PDO per factor and data format ("PAI Samples 10
  Channel 1" holds ten `Samples__ARRAY [i]` entries); the PDO groups
  (AlternativeSmMapping) pick them. A sample-array PDO is one whose entries
  all map sub-indices of one object and are named `... ARRAY [i]`; its factor
  is its entry count.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from .model import EsiDcOpMode, EsiOversampling, EsiPdo, EsiPdoGroup

_ARRAY_ELEMENT = re.compile(r"ARRAY \[\d+\]$")


def _sample_array_factor(pdo: EsiPdo) -> int | None:
    entries = pdo.entries
    if not entries or pdo.is_oversampling:
        return None
    index = entries[0].index
    if index == 0:
        return None
    for entry in entries:
        if entry.index != index or not _ARRAY_ELEMENT.search(entry.name):
            return None
    return len(entries)


def derive_oversampling(
    pdos: Sequence[EsiPdo],
    dc_op_modes: Sequence[EsiDcOpMode],
    groups: Sequence[EsiPdoGroup],
) -> EsiOversampling | None:
    """The device's oversampling description, or None if it has none."""
    templated = [pdo for pdo in pdos if pdo.is_oversampling]
    if templated:
        return _from_pdo_attributes(templated, dc_op_modes)
    return _from_pdo_groups(pdos, groups)


def _from_pdo_attributes(
    templated: list[EsiPdo], dc_op_modes: Sequence[EsiDcOpMode]
) -> EsiOversampling:
    indices = {pdo.index for pdo in templated}
    factors = {
        assignment.os_factor
        for mode in dc_op_modes
        for assignment in mode.pdos
        if assignment.pdo_index in indices and assignment.os_factor is not None
    }
    first = templated[0]
    if not factors and first.os_factor is not None:
        factors = {first.os_factor}
    default = next(
        (m.default_os_factor for m in dc_op_modes if m.default_os_factor is not None),
        first.os_factor,
    )
    return EsiOversampling(
        factors=tuple(sorted(factors)),
        default_factor=default,
        pdo_indices=tuple(pdo.index for pdo in templated),
        min_factor=first.os_min,
        max_factor=first.os_max,
        index_increment=first.os_index_inc,
        origin="pdo_attributes",
    )


def _from_pdo_groups(
    pdos: Sequence[EsiPdo], groups: Sequence[EsiPdoGroup]
) -> EsiOversampling | None:
    if not groups:
        return None
    factor_of: dict[int, int] = {}
    for pdo in pdos:
        factor = _sample_array_factor(pdo)
        if factor is not None:
            factor_of[pdo.index] = factor
    if len(set(factor_of.values())) < 2:
        return None
    group_factors: dict[str, int] = {}
    default: int | None = None
    for group in groups:
        found = {factor_of[i] for i in group.pdo_indices if i in factor_of}
        if len(found) == 1:
            group_factors[group.name] = found.pop()
            if group.is_default:
                default = group_factors[group.name]
    factors = sorted(set(factor_of.values()))
    return EsiOversampling(
        factors=tuple(factors),
        default_factor=default,
        pdo_indices=tuple(factor_of),
        min_factor=factors[0],
        max_factor=factors[-1],
        origin="pdo_groups",
        group_factors=group_factors,
    )
