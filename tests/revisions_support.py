"""Terminal YAML of other revisions of the DLS types, made from the real ESI.

`terminals/` holds one revision per type (mostly the newest); a real rack
runs older and newer ones. The tests make the YAML of other revisions from
the ESI files the repository ships (`tests/data/esi/beckhoff`, every revision
of the DLS types) exactly as `terminals generate TYPE --revision REV` does,
for the simulator to play those revisions truthfully (`sim --revisions`)
and for IOCs whose YAML is older than the rack.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Final

from fastcs_ethercat.esi.catalog import EsiCatalog
from fastcs_ethercat.terminals.esi_sources import open_catalog
from fastcs_ethercat.terminals.files import write_terminal_file
from fastcs_ethercat.terminals.generate import terminal_from_esi
from fastcs_ethercat.terminals.model import TerminalType
from tests.conftest import ESI_SUBSET

OLDER: Final = {
    "EL4134": 0x03F80000,  # the same symbols as 0x03fa0000
    "EL3104": 0x00100000,  # the same symbols and CoE as 0x00110000
    "EL2024": 0x00100000,  # the same symbols as 0x00130000
    "EL4732": 0x00000001,  # other symbols: `Cycle Counter`, `Sample 0` ...
    "EL1502": 0x00100000,  # other PDO groups: `Combined`, `Per-Channel`
}
"""Revisions older than the shipped YAML, and how they differ from it."""


@functools.cache
def catalog() -> EsiCatalog:
    return open_catalog([ESI_SUBSET])


def terminal_of(type_name: str, revision: int) -> TerminalType:
    """`type_name` at `revision`, generated from the shipped ESI."""
    return terminal_from_esi(catalog().load(type_name, revision))


def write_revisions(folder: Path, revisions: dict[str, int]) -> Path:
    """One file per (type, revision) in `folder`: `EL3104-0x00100000.yaml`."""
    folder.mkdir(parents=True, exist_ok=True)
    for type_name, revision in revisions.items():
        write_terminal_file(
            folder / f"{type_name}-0x{revision:08x}.yaml",
            {type_name: terminal_of(type_name, revision)},
        )
    return folder


def replace_with_revisions(folder: Path, revisions: dict[str, int]) -> Path:
    """Overwrite the types of `revisions` in a folder of terminal YAML with
    those revisions (an IOC whose YAML is older or newer than the rack)."""
    for type_name, revision in revisions.items():
        write_terminal_file(
            folder / f"{type_name}.yaml", {type_name: terminal_of(type_name, revision)}
        )
    return folder
