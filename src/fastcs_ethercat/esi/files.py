"""Read one ESI document and parse its devices, with one-line errors.

A document that is not well-formed XML (malformed, truncated, empty) or not
an ESI file (`<EtherCATInfo>` root) is unusable: `UserError` naming the file,
the line and, when the broken spot lies inside a `<Device>`, that device.
A well-formed file whose device is broken (missing element, bad number,
unknown data type) still yields its other devices; the broken one becomes a
warning (`UserError` instance) in the result.

Encodings come from the XML declaration (UTF-8 by default, ISO-8859-1 in
ELM37xx.xml); lxml decodes the bytes itself, CRLF is normalised by the XML
parser, so line numbers are those an editor shows.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from fastcs_ethercat.bounded import MAX_ESI_BYTES, read_bytes_bounded
from fastcs_ethercat.collector import held
from fastcs_ethercat.errors import UserError

from .device import identity_of, parse_device
from .memo import ParseMemo
from .model import EsiDevice, parse_esi_int
from .xmltext import Element, EsiFormatError

ROOT_TAG = "EtherCATInfo"
DEVICES_PATH = "Descriptions/Devices/Device"


def _parser(recover: bool = False) -> etree.XMLParser:
    """A fresh parser (lxml parsers must not be shared between threads)."""
    return etree.XMLParser(
        remove_blank_text=True,
        remove_comments=True,
        remove_pis=True,
        resolve_entities=False,
        no_network=True,
        huge_tree=False,  # libxml2's own limits on depth and text stay on
        recover=recover,
    )


def device_label(device: Element, position: int) -> str:
    """ "device EL3104 revision #x00100000" (or its position if unnamed)."""
    type_element = device.find("Type")
    name = (
        type_element.text.strip()
        if type_element is not None and type_element.text
        else ""
    )
    if not name:
        return f"device #{position + 1}"
    revision = type_element.get("RevisionNo") if type_element is not None else None
    return f"device {name}" + (f" revision {revision.strip()}" if revision else "")


def _device_around(data: bytes, line: int) -> str | None:
    """Label of the device a broken line falls in (salvaged in recover mode)."""
    try:
        root = etree.fromstring(data, _parser(recover=True))
    except etree.XMLSyntaxError:
        return None
    if root is None:
        return None
    label = None
    for position, device in enumerate(root.iterfind(DEVICES_PATH)):
        if (device.sourceline or 0) > line:
            break
        label = device_label(device, position)
    return label


def placed(message: str, source: str, element: Element) -> UserError:
    """A `UserError` naming the document and the line of `element`."""
    return UserError(message, path=source, where=str(element.sourceline or 1))


def read_root(data: bytes, source: str) -> Element:
    """The `<EtherCATInfo>` root of a document, or a one-line `UserError`."""
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as error:
        line = error.lineno or 1
        reason = str(error.msg or error).split(", line ")[0]
        where_device = _device_around(data, line) if data.strip() else None
        prefix = f"{where_device}: " if where_device else ""
        raise UserError(
            f"{prefix}not well-formed XML: {reason}", path=source, where=str(line)
        ) from None
    if root.tag != ROOT_TAG:
        raise placed(
            f"not an ESI file: root element is <{root.tag}>, expected <{ROOT_TAG}>",
            source,
            root,
        )
    return root


def vendor_id_of(root: Element, source: str) -> int:
    """`Vendor/Id` of the file (Beckhoff: 2)."""
    vendor = root.find("Vendor/Id")
    if vendor is None or not (vendor.text or "").strip():
        raise placed("ESI file has no <Vendor><Id>", source, root)
    try:
        return parse_esi_int(vendor.text or "")
    except ValueError:
        message = f"vendor id {vendor.text!r} is not a number"
        raise placed(message, source, vendor) from None


def device_elements(root: Element) -> list[Element]:
    """The `<Device>`s of a file in document order."""
    return list(root.iterfind(DEVICES_PATH))


def device_error(
    error: EsiFormatError, device: Element, position: int, source: str
) -> UserError:
    """`file:line: device X revision Y: message` as a `UserError`."""
    line = error.line or device.sourceline or 1
    return UserError(
        f"{device_label(device, position)}: {error.message}",
        path=source,
        where=str(line),
    )


def parse_device_element(
    device: Element,
    position: int,
    *,
    vendor_id: int,
    source: str,
    memo: ParseMemo | None = None,
) -> EsiDevice:
    """Parse one device; content problems become a placed `UserError`."""
    try:
        return parse_device(device, vendor_id=vendor_id, source=source, memo=memo)
    except EsiFormatError as error:
        raise device_error(error, device, position, source) from None
    except RecursionError:
        message = f"{device_label(device, position)}: nesting too deep"
        raise placed(message, source, device) from None


@dataclass(frozen=True, slots=True)
class EsiFileResult:
    """The devices of one file and the per-device errors met on the way."""

    source: str
    devices: tuple[EsiDevice, ...]
    warnings: tuple[UserError, ...]


@held()  # a burst that only builds objects: see `collector`
def parse_document(
    data: bytes, source: str, *, strict: bool = False, memo: ParseMemo | None = None
) -> EsiFileResult:
    """Parse every device of an ESI document held in memory (`memo`: shared
    with other documents of the same parse).

    Each device is emptied once parsed: the tree is freed piece by piece
    while it is still in the cache, rather than all at once at the end
    (a few % of a full parse)."""
    root = read_root(data, source)
    vendor_id = vendor_id_of(root, source)
    if memo is None:
        memo = ParseMemo()
    devices: list[EsiDevice] = []
    warnings: list[UserError] = []
    for position, device in enumerate(device_elements(root)):
        try:
            devices.append(
                parse_device_element(
                    device, position, vendor_id=vendor_id, source=source, memo=memo
                )
            )
        except UserError as error:
            if strict:
                raise
            warnings.append(error)
        device.clear()
    return EsiFileResult(
        source=source, devices=tuple(devices), warnings=tuple(warnings)
    )


def read_bytes(path: Path, source: str) -> bytes:
    """File content (at most `bounded.MAX_ESI_BYTES`), or a `UserError`."""
    return read_bytes_bounded(path, MAX_ESI_BYTES, what="ESI file", where=None)


def parse_file(path: Path | str, *, strict: bool = False) -> EsiFileResult:
    """Parse every device of one ESI file on disk."""
    source = str(path)
    return parse_document(read_bytes(Path(path), source), source, strict=strict)


def identity_or_none(device: Element) -> tuple[str, int, int] | None:
    """Identity of a device, None when its `<Type>` is unusable."""
    try:
        return identity_of(device)
    except EsiFormatError:
        return None
