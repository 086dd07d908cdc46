"""Small helpers to read ESI element text and attributes with line-aware errors.

Everything a device parser finds wrong is raised as `EsiFormatError` carrying
the source line of the offending element; the file layer turns it into a
one-line `UserError` naming file, line and device.
"""

from __future__ import annotations

from lxml import etree

from .model import MAX_ESI_BITS, parse_esi_int

Element = etree._Element


class EsiFormatError(Exception):
    """A problem inside one device, with the line of the element at fault."""

    def __init__(self, message: str, line: int | None) -> None:
        super().__init__(message)
        self.message = message
        self.line = line


def fail(element: Element, message: str) -> EsiFormatError:
    """An `EsiFormatError` placed at `element` (raise the result)."""
    return EsiFormatError(message, element.sourceline)


def first_at(element: Element, *path: str) -> Element | None:
    """What `element.find("A/B")` finds for `first_at(element, "A", "B")`
    (the first match in document order), without ElementPath's cost per
    call (4 us, 11 us for a path of three: more than the children walked)."""
    tag = path[0]
    for child in element:
        if child.tag == tag:
            if len(path) == 1:
                return child
            found = first_at(child, *path[1:])
            if found is not None:
                return found
    return None


def text_of(element: Element) -> str:
    """Stripped text of an element ("" when empty)."""
    value = element.text
    return value.strip() if value else ""


NUMBERS: dict[str | None, int] = {}
"""ESI number spellings already read -> value. A full parse of the shared
files reads ~120 000 numbers but only a few thousand spellings ("#x0000",
"16", "#x6000"): a dictionary lookup is several times cheaper than reading
`#x...` again. Hot loops look here first and call `int_of` on a miss."""
NUMBERS_MAX = 1 << 16
"""Spellings remembered at most (a bound for a process reading many files)."""


def _remembered(text: str) -> int:
    """`parse_esi_int` of a spelling, remembered in `NUMBERS`."""
    number = parse_esi_int(text)
    if len(NUMBERS) < NUMBERS_MAX:
        NUMBERS[text] = number
    return number


def int_of(element: Element, what: str) -> int:
    """Element text as an ESI number, or a placed error naming `what`."""
    value = element.text
    number = NUMBERS.get(value)
    if number is not None:
        return number
    if value is None or not value.strip():
        raise fail(element, f"{what} is empty")
    try:
        return _remembered(value)
    except ValueError:
        raise fail(element, f"{what} {shown(value)} is not a number") from None


def shown(text: str) -> str:
    """`text` quoted for a message, cut short when long."""
    text = text.strip()
    return repr(text if len(text) <= 24 else text[:20] + "...")


def check_bits(element: Element, what: str, bits: int, most: int = MAX_ESI_BITS) -> int:
    """`bits` if a usable bit count (0 to `most`), else a placed error."""
    if not 0 <= bits <= most:
        raise fail(element, f"{what} {bits} is out of range (0 to {most})")
    return bits


def int_attr(element: Element, name: str) -> int | None:
    """Attribute as an ESI number; None when absent."""
    value = element.get(name)
    if value is None:
        return None
    number = NUMBERS.get(value)
    if number is not None:
        return number
    try:
        return _remembered(value)
    except ValueError:
        raise fail(
            element,
            f"attribute {name}={shown(value)} of <{element.tag}> is not a number",
        ) from None


def bool_attr(element: Element, name: str) -> bool:
    """ESI booleans: "1"/"true" are true, anything else (or absent) false."""
    value = element.get(name)
    return value is not None and value.strip().lower() in ("1", "true")
