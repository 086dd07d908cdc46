"""One `<Device>` element -> `EsiDevice`.

The children of a device are walked once and dispatched on their tag (much
faster than one XPath per field on ~500 devices); each concern has its own
module (PDOs, dictionary, groups, oversampling).
"""

from __future__ import annotations

from fastcs_ethercat.safe_names import is_type_name

from .dictionary import parse_dictionary
from .groups import derive_groups
from .memo import ParseMemo, element_key
from .model import (
    EsiCoeObject,
    EsiDataType,
    EsiDcOpMode,
    EsiDcOpModePdo,
    EsiDevice,
    EsiHideType,
    EsiPdo,
    EsiPdoGroup,
    EsiSyncManager,
)
from .oversampling import derive_oversampling
from .pdos import PDO_TAGS, parse_pdo
from .xmltext import Element, fail, first_at, int_attr, int_of, text_of

ENGLISH = 1033


def identity_of(device: Element) -> tuple[str, int, int]:
    """(type name, product code, revision) from `<Type>`; errors are placed."""
    type_element = first_at(device, "Type")
    if type_element is None:
        raise fail(device, "<Device> has no <Type>")
    type_name = text_of(type_element)
    if not type_name:
        raise fail(type_element, "<Type> is empty")
    if not is_type_name(type_name):
        raise fail(
            type_element,
            f"<Type> {type_name[:40]!r} is not a terminal type name (letters, "
            "digits and _.+- only)",
        )
    product_code = int_attr(type_element, "ProductCode")
    if product_code is None:
        raise fail(type_element, f"<Type> of {type_name} has no ProductCode")
    revision = int_attr(type_element, "RevisionNo")
    return type_name, product_code, revision if revision is not None else 0


def describe(names: dict[int, str], fallback: str) -> str:
    """English name (LcId 1033), else the first name, else `fallback`."""
    if ENGLISH in names:
        return names[ENGLISH]
    return next(iter(names.values()), fallback)


def name_of(element: Element, names: dict[int, str]) -> None:
    """Record a `<Name LcId=...>` (a missing LcId counts as English)."""
    lcid_text = element.get("LcId")
    try:
        lcid = int(lcid_text) if lcid_text is not None else ENGLISH
    except ValueError:
        raise fail(element, f"LcId {lcid_text!r} is not a number") from None
    names.setdefault(lcid, text_of(element))


def _hide_type(element: Element) -> EsiHideType:
    return EsiHideType(
        product_code=int_attr(element, "ProductCode"),
        revision=int_attr(element, "RevisionNo"),
        name=(element.get("ProductRevision") or text_of(element)).strip(),
    )


def _dc_op_mode(element: Element) -> EsiDcOpMode:
    name = ""
    description = ""
    assign_activate: int | None = None
    pdos: list[EsiDcOpModePdo] = []
    default_factor: int | None = None
    for child in element:
        tag = child.tag
        if tag == "Name":
            name = text_of(child)
        elif tag == "Desc":
            description = text_of(child)
        elif tag == "AssignActivate":
            assign_activate = int_of(child, "AssignActivate")
        elif tag == "Sm":
            sm = int_attr(child, "No")
            if sm is None:
                raise fail(child, f"DC op mode {name!r}: <Sm> has no No attribute")
            for pdo in child.iterfind("Pdo"):
                index = int_of(pdo, f"DC op mode {name!r} Pdo")
                pdos.append(EsiDcOpModePdo(sm, index, int_attr(pdo, "OSFac")))
        elif tag == "VendorSpecific":
            oversampling = child.find("TwinCAT/Oversampling")
            if oversampling is not None:
                default_factor = int_attr(oversampling, "DefaultFactor")
    return EsiDcOpMode(
        name=name,
        description=description,
        assign_activate=assign_activate,
        pdos=tuple(pdos),
        default_os_factor=default_factor,
    )


def _dc_op_modes(element: Element, memo: ParseMemo | None) -> tuple[EsiDcOpMode, ...]:
    """The `OpMode`s of a `<Dc>` (183 in the shared files, 36 distinct)."""
    if memo is None:
        return tuple(_dc_op_mode(mode) for mode in element.iterchildren("OpMode"))
    key = element_key(element)
    modes = memo.dc_op_modes.get(key)
    if modes is None:
        modes = tuple(_dc_op_mode(mode) for mode in element.iterchildren("OpMode"))
        memo.dc_op_modes[key] = modes
    return modes


def _groups(
    twincat: Element | None,
    pdos: list[EsiPdo],
    sync_managers: list[EsiSyncManager],
    memo: ParseMemo | None,
) -> tuple[EsiPdoGroup, ...]:
    """`derive_groups`, once per memo for the same `TwinCAT` text, PDOs
    (shared objects of the memo, so their identities) and sync managers."""
    if memo is None:
        return derive_groups(twincat, pdos, sync_managers)
    key = (
        "" if twincat is None else element_key(twincat),
        tuple(map(id, pdos)),
        tuple(sync_managers),
    )
    groups = memo.groups.get(key)
    if groups is None:
        groups = memo.groups[key] = derive_groups(twincat, pdos, sync_managers)
    return groups


def parse_device(
    device: Element, *, vendor_id: int, source: str, memo: ParseMemo | None = None
) -> EsiDevice:
    """Everything about one device; raises `EsiFormatError` for bad content.

    `memo` shares identical elements between the devices of one document.
    """
    type_name, product_code, revision = identity_of(device)
    names: dict[int, str] = {}
    group_type = ""
    hide_types: list[EsiHideType] = []
    tx_pdos: list[EsiPdo] = []
    rx_pdos: list[EsiPdo] = []
    sync_managers: list[EsiSyncManager] = []
    dc_op_modes: list[EsiDcOpMode] = []
    twincat: Element | None = None
    has_mailbox = False
    has_coe = False
    data_types: dict[str, EsiDataType] = {}
    coe_objects: dict[int, EsiCoeObject] = {}
    for child in device:
        tag = child.tag
        if tag in PDO_TAGS:
            direction = PDO_TAGS[tag]
            if memo is None:
                pdo = parse_pdo(child, direction)
            else:
                key = element_key(child)
                pdo = memo.pdos.get(key)
                if pdo is None:
                    pdo = memo.pdos[key] = parse_pdo(child, direction, memo, key)
            (tx_pdos if direction == "tx" else rx_pdos).append(pdo)
        elif tag == "Name":
            name_of(child, names)
        elif tag == "GroupType":
            group_type = text_of(child)
        elif tag == "HideType":
            hide_types.append(_hide_type(child))
        elif tag == "Sm":
            sync_managers.append(
                EsiSyncManager(
                    number=len(sync_managers),
                    kind=text_of(child),
                    start_address=int_attr(child, "StartAddress"),
                    default_size=int_attr(child, "DefaultSize"),
                )
            )
        elif tag == "Info":
            twincat = first_at(child, "VendorSpecific", "TwinCAT")
        elif tag == "Mailbox":
            has_mailbox = True
            has_coe = first_at(child, "CoE") is not None
        elif tag == "Dc":
            dc_op_modes.extend(_dc_op_modes(child, memo))
        elif tag == "Profile":
            dictionary = first_at(child, "Dictionary")
            if dictionary is not None:
                data_types, coe_objects = parse_dictionary(dictionary, memo)
    pdos = tx_pdos + rx_pdos
    groups = _groups(twincat, pdos, sync_managers, memo)
    default_group = next((g.name for g in groups if g.is_default), None)
    return EsiDevice(
        type_name=type_name,
        vendor_id=vendor_id,
        product_code=product_code,
        revision=revision,
        description=describe(names, type_name),
        group_type=group_type,
        tx_pdos=tuple(tx_pdos),
        rx_pdos=tuple(rx_pdos),
        pdo_groups=groups,
        default_group=default_group,
        data_types=data_types,
        coe_objects=coe_objects,
        oversampling=derive_oversampling(pdos, dc_op_modes, groups),
        source=source,
        source_line=device.sourceline or 0,
        names=names,
        hide_types=tuple(hide_types),
        sync_managers=tuple(sync_managers),
        dc_op_modes=tuple(dc_op_modes),
        has_mailbox=has_mailbox,
        has_coe=has_coe,
    )
