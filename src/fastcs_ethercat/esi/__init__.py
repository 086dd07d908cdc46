"""Beckhoff ESI XML -> typed device descriptions.

Typical use::

    catalog = build_catalog("../shared/esi")      # cheap, cached listing
    catalog.revisions("EL3104")                    # every revision
    device = catalog.load("EL3104")                # newest revision, full parse
    device.pdo_groups, device.default_group

`model` holds the dataclasses (the stable contract), `catalog` the listing and
lookup, `files` the per-document parser, `groups` the PDO-group rules.
"""

from typing import TYPE_CHECKING, Final

from fastcs_ethercat.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .catalog import (
        EsiCatalog,
        EsiParseResult,
        build_catalog,
        load_device,
        parse_all,
    )
    from .channels import channel_template
    from .files import EsiFileResult, parse_document, parse_file
    from .model import (
        CatalogEntry,
        EsiCoeObject,
        EsiCoeSubItem,
        EsiDataType,
        EsiDataTypeSubItem,
        EsiDcOpMode,
        EsiDcOpModePdo,
        EsiDevice,
        EsiEntry,
        EsiEnumItem,
        EsiHideType,
        EsiOversampling,
        EsiPdo,
        EsiPdoGroup,
        EsiSyncManager,
        parse_esi_int,
    )

_EXPORTS: Final = {
    "EsiCatalog": "catalog",
    "EsiParseResult": "catalog",
    "build_catalog": "catalog",
    "load_device": "catalog",
    "parse_all": "catalog",
    "channel_template": "channels",
    "EsiFileResult": "files",
    "parse_document": "files",
    "parse_file": "files",
    "CatalogEntry": "model",
    "EsiCoeObject": "model",
    "EsiCoeSubItem": "model",
    "EsiDataType": "model",
    "EsiDataTypeSubItem": "model",
    "EsiDcOpMode": "model",
    "EsiDcOpModePdo": "model",
    "EsiDevice": "model",
    "EsiEntry": "model",
    "EsiEnumItem": "model",
    "EsiHideType": "model",
    "EsiOversampling": "model",
    "EsiPdo": "model",
    "EsiPdoGroup": "model",
    "EsiSyncManager": "model",
    "parse_esi_int": "model",
}
"""Public name -> the submodule it lives in, imported when first used: a user
of the dataclasses does not import the parser."""
__getattr__ = lazy_exports(__name__, _EXPORTS)

__all__ = [
    "CatalogEntry",
    "EsiCatalog",
    "EsiCoeObject",
    "EsiCoeSubItem",
    "EsiDataType",
    "EsiDataTypeSubItem",
    "EsiDcOpMode",
    "EsiDcOpModePdo",
    "EsiDevice",
    "EsiEntry",
    "EsiEnumItem",
    "EsiFileResult",
    "EsiHideType",
    "EsiOversampling",
    "EsiParseResult",
    "EsiPdo",
    "EsiPdoGroup",
    "EsiSyncManager",
    "build_catalog",
    "channel_template",
    "load_device",
    "parse_all",
    "parse_document",
    "parse_esi_int",
    "parse_file",
]
