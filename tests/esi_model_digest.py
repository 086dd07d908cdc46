"""A digest of everything the ESI parser says about each device, to pin it.

The parser is tuned for speed (see the README's Benchmarks); a rewrite must
give the very same model. `outline` turns a parsed device into plain data
(class name, field names and values; mappings in their order), independent
of how the model classes are built (dataclass or NamedTuple), and `digests`
gives one sha256 per device (and per warning) of an ESI source, with paths
relative to it. `tests/data/esi/model-digests.json` holds the digests of the
ESI the tests ship and of `../shared/esi`; `tests/test_esi_model_digest.py`
compares against them.

`python -m tests.esi_model_digest` (from the repository root) writes that
file again: only when the model is meant to change (a new field), and say so
in the commit.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Mapping
from pathlib import Path

from fastcs_ethercat.esi import parse_all
from tests.conftest import EL3356_FIXTURE, ESI_SUBSET, SHARED_ESI, TEST_DATA

DIGESTS_FILE = TEST_DATA / "esi" / "model-digests.json"
SHIPPED_ESI = (ESI_SUBSET, EL3356_FIXTURE, TEST_DATA / "esi" / "bad")
"""The ESI the tests ship, broken files included (their warnings count)."""

Outline = None | bool | int | str | list["Outline"]


def outline(value: object, root: str) -> Outline:
    """Plain, ordered data for a model value; `source` paths made relative."""
    if value is None or isinstance(value, bool | int | str):
        if isinstance(value, str) and value.startswith(root):
            return value[len(root) :]
        return value
    fields = getattr(value, "_fields", None) or getattr(
        value, "__dataclass_fields__", None
    )
    if fields is not None:
        return [
            type(value).__name__,
            *([name, outline(getattr(value, name), root)] for name in fields),
        ]
    if isinstance(value, Mapping):
        pairs = value.items()
        return ["map", *([outline(k, root), outline(v, root)] for k, v in pairs)]
    if isinstance(value, tuple | list):
        return ["seq", *(outline(item, root) for item in value)]
    raise TypeError(f"no outline for {type(value).__name__}")


def _sha(data: Outline) -> str:
    text = json.dumps(data, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()


def digests(sources: tuple[Path, ...], root: Path) -> dict[str, str]:
    """`file #position type revision` -> digest for every device of `sources`,
    and `warning N` -> the text of each warning; paths relative to `root`."""
    prefix = str(root) + "/"
    result = parse_all(list(sources))
    found: dict[str, str] = {}
    position: dict[str, int] = {}
    for device in result.devices:
        source = str(outline(device.source, prefix))
        number = position[source] = position.get(source, -1) + 1
        key = f"{source} #{number} {device.type_name} #x{device.revision:08x}"
        found[key] = _sha(outline(device, prefix))
    for number, warning in enumerate(result.warnings):
        found[f"warning {number}"] = str(outline(str(warning), prefix))
    return found


def shipped_digests() -> dict[str, str]:
    return digests(SHIPPED_ESI, TEST_DATA / "esi")


def shared_digests() -> dict[str, str]:
    return digests((SHARED_ESI,), SHARED_ESI)


def main() -> None:
    if not SHARED_ESI.is_dir():
        sys.exit(f"needs the full ESI set in {SHARED_ESI}")
    document = {"shipped": shipped_digests(), "shared": shared_digests()}
    DIGESTS_FILE.write_text(json.dumps(document, indent=1, sort_keys=True) + "\n")
    print(
        f"{DIGESTS_FILE}: {len(document['shipped'])} shipped, "
        f"{len(document['shared'])} shared"
    )


if __name__ == "__main__":
    main()
