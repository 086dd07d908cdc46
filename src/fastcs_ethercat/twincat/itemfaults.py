"""Per-symbol read errors: chosen symbols fail, everything else reads fine.

TwinCAT answers a sum read (0xF080) with one result per item, and an item's
error does not fail the others (facts section 3). The `error` fault with
`symbols` plays that: every read whose bytes (or bits) touch a named symbol
answers the fault's ADS error code, as a sum-read item, a single Read of the
image, or a read by handle or by name. Writes are not affected.

Symbols are kept by name and looked up in the current symbol table on every
request, so a fault follows its symbol through an online change (and stops
applying if the symbol is gone).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from fastcs_ethercat.twincat.layout import AREAS, ImageArea
from fastcs_ethercat.twincat.symtab import Resolved, SymbolTable


@dataclass(frozen=True, slots=True)
class FailingBits:
    """Bits [first, end) of one image area, answered with ADS error `code`."""

    area: ImageArea
    first: int
    end: int
    code: int

    @classmethod
    def of(cls, found: Resolved, code: int) -> FailingBits:
        return cls(
            found.area,
            found.bit_address,
            found.bit_address + max(found.type.bit_size, 1),
            code,
        )


def bits_read(group: int, offset: int, length: int) -> tuple[ImageArea, int, int]:
    """The area and bits [first, end) a read of the image asks for; raises
    LookupError for a group that is not an image.

    A byte group reads `length` bytes from byte `offset`; a bit group reads
    `length` bits (one byte each) from bit `offset`.
    """
    for area in AREAS:
        if group == area.byte_group:
            return area, 8 * offset, 8 * (offset + length)
        if group == area.bit_group:
            return area, offset, offset + max(length, 1)
    raise LookupError(f"group 0x{group:X} is not a process image")


def failing_bits(table: SymbolTable, errors: dict[str, int]) -> list[FailingBits]:
    """Where the failing symbols are now (names the table lacks are skipped)."""
    found = ((table.resolve(name), code) for name, code in errors.items())
    return [FailingBits.of(symbol, code) for symbol, code in found if symbol]


def error_of(
    failing: Sequence[FailingBits], area: ImageArea, first: int, end: int
) -> int:
    """The error code of a read of bits [first, end) of `area` (0: none)."""
    for bits in failing:
        if bits.area is area and bits.first < end and first < bits.end:
            return bits.code
    return 0


def item_error(
    failing: Sequence[FailingBits], group: int, offset: int, length: int
) -> int:
    """The error code of one read (sum-read item or single Read), 0 if none."""
    if not failing:
        return 0
    try:
        area, first, end = bits_read(group, offset, length)
    except LookupError:
        return 0
    return error_of(failing, area, first, end)


__all__ = [
    "FailingBits",
    "bits_read",
    "error_of",
    "failing_bits",
    "item_error",
]
