"""`<TxPdo>` / `<RxPdo>` elements -> `EsiPdo` with its `EsiEntry`s.

Quirks of the real files handled here: gap entries with `<Index>#x0</Index>`
and no SubIndex/Name/DataType, hex in any case and width (`#x1A00`,
`#x1a00`, `#x98`), PDOs on Sm 0 (devices without mailbox), oversampling
attributes (`OSFac`, `OSMin`, `OSMax`, `OSIndexInc`), names with stray
surrounding spaces (stripped). Old generic catalogues give PDOs only by
reference (`<TxPdo Ref="#x1a00" Chn="1"/>`): such a device is not usable
and says so.
"""

from __future__ import annotations

from .channels import channel_template
from .memo import ParseMemo, shared
from .model import (
    MAX_PDO_ENTRIES,
    MAX_PDO_ENTRY_BITS,
    EsiEntry,
    EsiPdo,
    PdoDirection,
    new_record,
)
from .xmltext import (
    NUMBERS,
    Element,
    bool_attr,
    check_bits,
    fail,
    int_attr,
    int_of,
    text_of,
)

PDO_TAGS: dict[str, PdoDirection] = {"TxPdo": "tx", "RxPdo": "rx"}


def parse_entry(element: Element) -> EsiEntry:
    """One `<Entry>`; Index and BitLen are required, the rest optional."""
    index: int | None = None
    subindex = 0
    bit_len: int | None = None
    name = ""
    data_type: str | None = None
    comment: str | None = None
    dscale: str | None = None
    for child in element:  # the hottest loop of a PDO: numbers looked up inline
        tag = child.tag
        text = child.text
        if tag == "Index":
            index = NUMBERS.get(text)
            if index is None:
                index = int_of(child, "entry Index")
        elif tag == "SubIndex":
            subindex = NUMBERS.get(text)
            if subindex is None:
                subindex = int_of(child, "entry SubIndex")
        elif tag == "BitLen":
            bit_len = NUMBERS.get(text)
            if bit_len is None:
                bit_len = int_of(child, "entry BitLen")
        elif tag == "Name":
            name = text.strip() if text else ""
        elif tag == "DataType":
            data_type = (text.strip() or None) if text else None
            dscale = child.get("DScale")
        elif tag == "Comment":
            comment = (text.strip() or None) if text else None
    if index is None:
        raise fail(element, f"PDO entry {name!r} has no <Index>")
    if bit_len is None:
        raise fail(element, f"PDO entry {name!r} has no <BitLen>")
    check_bits(element, f"BitLen of PDO entry {name!r}", bit_len, MAX_PDO_ENTRY_BITS)
    if not (0 <= index <= 0xFFFF and 0 <= subindex <= 0xFF):
        raise fail(element, f"PDO entry {name!r}: index or subindex out of range")
    return new_record(
        EsiEntry, (index, subindex, bit_len, name, data_type, comment, dscale)
    )


def parse_pdo(
    element: Element,
    direction: PdoDirection,
    memo: ParseMemo | None = None,
    key: str = "",
) -> EsiPdo:
    """One PDO element with its entries and exclusions (with a `memo` and
    the element's `key`, each distinct entry is parsed once)."""
    index: int | None = None
    name: str | None = None
    excludes: list[int] = []
    entry_elements: list[Element] = []
    for child in element:
        tag = child.tag
        if tag == "Entry":
            entry_elements.append(child)
        elif tag == "Index":
            index = int_of(child, "PDO Index")
        elif tag == "Name":
            if name is None:
                name = text_of(child)
        elif tag == "Exclude":
            excludes.append(int_of(child, "PDO Exclude"))
    if len(entry_elements) > MAX_PDO_ENTRIES:
        raise fail(
            element,
            f"PDO has {len(entry_elements)} entries, more than a PDO can map "
            f"({MAX_PDO_ENTRIES})",
        )
    known = memo.entries if memo else None
    entries = shared(parse_entry, entry_elements, "Entry", key, known)
    if index is None:
        reference = element.get("Ref")
        if reference is not None:
            raise fail(
                element,
                f"<{element.tag} Ref={reference.strip()!r}> only refers to a PDO "
                "(a catalogue placeholder, not a device description)",
            )
        raise fail(element, f"<{element.tag}> has no <Index>")
    if name is None:
        raise fail(element, f"PDO #x{index:04x} has no <Name>")
    channel, template = channel_template(name)
    return EsiPdo(
        index=index,
        name=name,
        direction=direction,
        sm=int_attr(element, "Sm"),
        fixed=bool_attr(element, "Fixed"),
        mandatory=bool_attr(element, "Mandatory"),
        excludes=tuple(excludes),
        entries=tuple(entries),
        channel=channel,
        channel_template=template,
        virtual=bool_attr(element, "Virtual"),
        su=int_attr(element, "Su"),
        os_factor=int_attr(element, "OSFac"),
        os_min=int_attr(element, "OSMin"),
        os_max=int_attr(element, "OSMax"),
        os_index_inc=int_attr(element, "OSIndexInc"),
    )
