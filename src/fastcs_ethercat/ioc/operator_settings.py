"""What operators set on the served records survives a restart.

softioc's autosave keeps the chosen fields of each record in one file of the
`autosave_dir` folder (`<prefix>.softsav`, written every `SAVE_PERIOD_S`
when something changed, and when the IOC stops) and, at the next start,
writes them into the records before the database is loaded: the limits are
back before the first client connects. A saved field wins over the IOC's
default for it (as with EPICS's autosave): delete the file to take new
defaults after an upgrade.

Kept: an operator's settings, by record type: alarm limits and severities,
hysteresis and deadbands, the description. Never a value: an output's value
is the PLC's (restoring it would write to the PLC at boot, a command bit
such as `Tara` or `SetCounter` would fire), and an input's is the next
poll's.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from fastcs_ethercat.ioc.dbaccess import get_text
from fastcs_ethercat.ioc.fastcs_adapter import record_names
from fastcs_ethercat.ioc.pvlists import OPERATOR_FIELDS

if TYPE_CHECKING:
    from fastcs.controllers import ControllerAPI

logger = logging.getLogger(__name__)

SAVE_PERIOD_S: Final = 10.0
"""How often softioc's autosave looks for changed settings."""


class _SavedRecord:
    """One record as softioc's autosave uses it: a field read from the
    running database (EPICS's `dbGetField`), a field restored into the
    record before the database is loaded (epicsdbbuilder's field)."""

    _name: str
    _record: Any

    def __init__(self, name: str, record: Any) -> None:
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_record", record)

    def get_field(self, field: str) -> str:
        return get_text(f"{self._name}.{field}")

    def __setattr__(self, field: str, value: Any) -> None:
        setattr(self._record, field, value)


def keep_operator_settings(
    directory: Path, name: str, controller_apis: Iterable[ControllerAPI]
) -> int:
    """Have softioc's autosave keep the settings of every record (call after
    the records are made, before the database is loaded); how many records."""
    from epicsdbbuilder import LookupRecord
    from softioc import autosave

    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:  # as with the PV lists: a warning, never the IOC
        logger.warning(
            "cannot keep the operators' settings in %s: %s; serving without autosave",
            directory,
            error.strerror,
        )
        return 0
    autosave.configure(
        directory, name, save_period=SAVE_PERIOD_S, timestamped_backups=False
    )
    kept = 0
    for api in controller_apis:
        for controller_api in api.walk_api():
            for attribute in controller_api.attributes.values():
                for record_name in _record_names(attribute):
                    try:
                        record: Any = LookupRecord(record_name)
                    except KeyError:
                        continue
                    fields = OPERATOR_FIELDS.get(type(record).__name__)
                    if fields:
                        saved = _SavedRecord(record_name, record)
                        autosave.add_pv_to_autosave(saved, record_name, list(fields))
                        kept += 1
    return kept


def _record_names(attribute: Any) -> list[str]:
    if not attribute.enabled:
        return []
    return [name for name in record_names(attribute) if name]
