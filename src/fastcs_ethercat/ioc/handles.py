"""Symbol handles for a master's points: what its reads and writes address.

An address (index group and offset) resolved at discovery goes on pointing
at the same bytes after an online change, where another symbol may now sit:
TwinCAT then serves those bytes without complaint. A handle taken by name
(0xF003) fails instead (0x711, symbol version invalid) once the table
changed, so nothing is read from or written to the wrong symbol; the IOC
resolves again and goes on.

Reads take one handle per source symbol (the table entry a point's bytes are
in: members of one structure share it); writes one per written symbol (a
member, or a bit member, reaches exactly its own bytes or bit, so no byte
another output shares is read and written back). Each read handle is taken
in the same sum request as the symbol's description (0xF009): a symbol whose
type or size is not what discovery saw (the table changed between the upload
and now) is not read with that handle, it is a problem to resolve again.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Final

from fastcs_ethercat.ads.client import AdsClient, AdsError
from fastcs_ethercat.ads.constants import (
    AdsReturnCode,
    IndexGroup,
    describe_return_code,
)
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.sums import SumReadWriteItem
from fastcs_ethercat.ads.symbols import (
    SYMBOL_INFO_SIZE,
    AdsSymbolEntry,
    encode_symbol_name,
)
from fastcs_ethercat.ads.wire import U32
from fastcs_ethercat.ioc.plan import Point

logger = logging.getLogger(__name__)

RELEASE_TIMEOUT_S: Final = 0.5
"""Releasing old handles is a courtesy to the target: never waited for long."""


@dataclass
class PointHandles:
    """The handles of one master's points, taken in one go."""

    reads: dict[str, int] = field(default_factory=dict)
    """Source symbol -> read handle."""
    writes: dict[str, int] = field(default_factory=dict)
    """Written symbol -> write handle."""
    problems: dict[str, str] = field(default_factory=dict)
    """Symbol -> why it has no usable handle."""
    unused: list[int] = field(default_factory=list)
    """Handles taken but not used (their symbol changed): given back with
    the others."""

    def all(self) -> list[int]:
        """Every handle taken, to give back."""
        return sorted(
            set(self.reads.values()) | set(self.writes.values()) | set(self.unused)
        )

    def read_problem(self, point: Point) -> str | None:
        """Why `point` cannot be read, or None."""
        if point.source_name in self.reads:
            return None
        return self.problems.get(point.source_name, "no handle")

    def write_problem(self, point: Point) -> str | None:
        if point.symbol in self.writes:
            return None
        return self.problems.get(point.symbol, "no handle")


async def acquire(
    client: AdsClient, points: Iterable[Point], *, writes: bool = True
) -> PointHandles:
    """Handles for reading every point and (with `writes`) writing every
    writable one.

    Raises AdsError only when the requests themselves fail (the target does
    not answer); a symbol that has no handle is a problem, not an error.
    """
    shapes: dict[str, tuple[str, int]] = {}
    written: list[str] = []
    for point in points:
        shapes.setdefault(point.source_name, point.source_shape)
        if writes and point.writable and point.symbol not in written:
            written.append(point.symbol)
    sources = list(shapes)
    items: list[SumReadWriteItem] = []
    for name in sources:
        encoded = encode_symbol_name(name)
        items.append(SumReadWriteItem(IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, encoded))
        items.append(
            SumReadWriteItem(
                IndexGroup.SYM_INFO_BY_NAME_EX, 0, SYMBOL_INFO_SIZE, encoded
            )
        )
    items += [
        SumReadWriteItem(IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, encode_symbol_name(name))
        for name in written
    ]
    outcomes = await client.sum_read_write(items) if items else []
    found = PointHandles()
    for n, name in enumerate(sources):
        handle, info = outcomes[2 * n], outcomes[2 * n + 1]
        problem = _handle_problem(handle) or _shape_problem(info, shapes[name])
        number = _handle(handle)
        if problem is None and number is not None:
            found.reads[name] = number
        else:
            found.problems[name] = problem or "no handle"
            if number is not None:
                found.unused.append(number)
    for name, outcome in zip(written, outcomes[2 * len(sources) :], strict=True):
        number = _handle(outcome)
        if number is None:
            found.problems[name] = _handle_problem(outcome) or "no handle"
        else:
            found.writes[name] = number
    return found


async def release(client: AdsClient, handles: Sequence[int]) -> None:
    """Give handles back, briefly and quietly: after an online change they are
    invalid anyway, and a target that does not answer is not waited for."""
    if not handles:
        return
    try:
        await asyncio.wait_for(client.release_handles(handles), RELEASE_TIMEOUT_S)
    except (AdsError, TimeoutError, OSError) as error:
        logger.debug("%d handles not released: %s", len(handles), error)


def _handle(outcome: tuple[int, bytes]) -> int | None:
    result, data = outcome
    if result != AdsReturnCode.NO_ERROR or len(data) != U32.size:
        return None
    return int(U32.unpack(data)[0])


def _handle_problem(outcome: tuple[int, bytes]) -> str | None:
    result, data = outcome
    if result == AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND:
        return "not in the symbol table any more"
    if result != AdsReturnCode.NO_ERROR:
        return f"no handle: {describe_return_code(result)}"
    if len(data) != U32.size:
        return f"no handle: the target answered {len(data)} bytes"
    return None


def _shape_problem(outcome: tuple[int, bytes], wanted: tuple[str, int]) -> str | None:
    """Why the symbol as the target describes it now is not what was resolved."""
    result, data = outcome
    if result != AdsReturnCode.NO_ERROR:
        return f"no description: {describe_return_code(result)}"
    try:
        entry, _ = AdsSymbolEntry.decode_at(data)
    except AdsCodecError as error:
        return f"unreadable description: {error}"
    type_name, size = wanted
    if entry.size != size or entry.type_name.strip().casefold() != (
        type_name.strip().casefold()
    ):
        return (
            f"is {entry.type_name} ({entry.size} bytes) now, was {type_name} "
            f"({size} bytes) at discovery"
        )
    return None
