"""The ESI the tests ship: the devices they use, cut from the real Beckhoff files.

A plain clone has no `../shared/esi` (the 13 real files, 29.8 MB), so the
tests read `tests/data/esi/beckhoff/`: the same file names, each holding the
bytes of its source file with only the `<Device>` elements the tests use
(every revision of the terminal types in use at Diamond, one revision of each
vendor quirk the parser must take). Everything else of a file, its header
(vendor, groups) and its trailer, is kept as it is. Cutting is byte-wise, so
a kept device is the source's bytes, CRLF and encoding included.

`python -m tests.esi_subset SRC` writes the subset from a copy of the shared
files; `tests/test_esi_subset.py` checks the shipped files against it.
"""

from __future__ import annotations

import hashlib
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from fastcs_ethercat.esi import parse_esi_int
from tests.conftest import DLS_TYPES as SHIPPED_TYPES
from tests.conftest import ESI_SUBSET

DLS_TYPES: frozenset[str] = frozenset(SHIPPED_TYPES) - {"EL3356-0010"}
"""Kept in every revision (EL3356-0010 is not in the shared files)."""

QUIRKS: frozenset[tuple[str, int]] = frozenset(
    {
        ("EL1512", 0x00150000),  # AlternativeSmMapping the Exclude rule must match
        ("EL2014", 0x00100000),  # a mapping naming an undefined PDO
        ("EL2252", 0x00110000),  # a PDO index defined twice
        ("EL2258", 0x00100000),  # an empty <Pdo/> in a mapping
        ("EL3102", 0x00110000),  # Exclude graph with per-channel mixes
        ("EL3632", 0x00100000),  # a mapping with only an empty <Name/>
        ("EP3184-0002", 0x00110002),  # one unnamed mapping
    }
)
"""Single revisions of other types, each for the vendor quirk it shows."""

DEVICE_START = re.compile(rb"<Device[\s>]")
DEVICE_END = b"</Device>"
DEVICES_TAG = b"<Devices>"


@dataclass(frozen=True)
class DeviceSpan:
    """One `<Device>` of a file: its type, revision and bytes (with the
    whitespace before it, so kept devices sit where they sat)."""

    type_name: str
    revision: int
    start: int
    end: int


def wanted(type_name: str, revision: int) -> bool:
    return type_name in DLS_TYPES or (type_name, revision) in QUIRKS


def device_spans(data: bytes, name: str) -> list[DeviceSpan]:
    """The devices of an ESI file in order, found byte-wise and named by lxml."""
    identities = []
    for device in etree.fromstring(data).iterfind("Descriptions/Devices/Device"):
        type_element = device.find("Type")
        if type_element is None:
            raise ValueError(f"{name}: a device without <Type>")
        revision = parse_esi_int(type_element.get("RevisionNo", "0"))
        identities.append(((type_element.text or "").strip(), revision))
    position = data.index(DEVICES_TAG) + len(DEVICES_TAG)
    spans = []
    for type_name, revision in identities:
        start = DEVICE_START.search(data, position)
        if start is None or data[position : start.start()].strip():
            raise ValueError(f"{name}: unexpected text before device {type_name}")
        end = data.index(DEVICE_END, start.start()) + len(DEVICE_END)
        spans.append(DeviceSpan(type_name, revision, position, end))
        position = end
    if DEVICE_START.search(data, position):
        raise ValueError(f"{name}: more <Device> tags than lxml found")
    return spans


def cut(data: bytes, name: str) -> tuple[bytes, list[DeviceSpan]]:
    """`data` with only the wanted devices, and those devices."""
    spans = device_spans(data, name)
    if not spans:
        return data, []
    kept = [span for span in spans if wanted(span.type_name, span.revision)]
    body = b"".join(data[span.start : span.end] for span in kept)
    return data[: spans[0].start] + body + data[spans[-1].end :], kept


def source_files(source: Path) -> Iterator[Path]:
    """The ESI files of the shared directory, in a stable order."""
    yield from sorted(source.rglob("*.xml"))


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def kept_text(kept: list[DeviceSpan]) -> str:
    """`EL1502 (9 revisions), EL1512 #x00150000`: what a subset file holds."""
    revisions: dict[str, list[int]] = {}
    for span in kept:
        revisions.setdefault(span.type_name, []).append(span.revision)
    return ", ".join(
        f"{name} ({len(found)} revisions)"
        if len(found) > 1
        else f"{name} #x{found[0]:08x}"
        for name, found in sorted(revisions.items())
    )


def write_subset(source: Path, target: Path = ESI_SUBSET) -> None:
    """Cut every file of `source` into `target` (same relative names) and
    print the README's table rows."""
    for path in source_files(source):
        relative = path.relative_to(source)
        data = path.read_bytes()
        subset, kept = cut(data, str(relative))
        (target / relative).parent.mkdir(parents=True, exist_ok=True)
        (target / relative).write_bytes(subset)
        print(
            f"| `{relative.as_posix()}` | `{sha256(data)}` | {len(data)} "
            f"| {len(subset)} | {kept_text(kept)} |"
        )


if __name__ == "__main__":
    write_subset(Path(sys.argv[1]))
