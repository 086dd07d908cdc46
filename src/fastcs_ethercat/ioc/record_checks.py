"""Check record fields as softioc does, each field and value once.

FastCS makes one softioc record per CA PV, and softioc checks every field
value against the EPICS database definition (epicsdbbuilder's
`ValidateDbField.ValidFieldValue`): it walks the record type's fields from
the first to find the named one (two ctypes calls per field, ~30 fields on
average), then asks `dbVerify`. About 0.3 ms per record, three seconds for a
rack of 500 terminals, yet most records of one type repeat the same fields
with the same values (DTYP, SCAN, PINI, ZNAM, menus ...).

`dbVerify`'s verdict depends only on the field's definition and the value's
text, so a (field, value) that passed once for a record type passes again:
it is remembered per record type. A new value (INP/OUT name every record
apart) is verified with the cursor put on its field by position, learnt once
per record type from the same walk (`dbFirstField`, then `dbNextField` n
times, no names read). A value that fails is checked again the library's
way, so the error raised is the library's own. Installed once per IOC
process, before FastCS makes the records.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

_PASSED = "_fastcs_ethercat_passed"
"""Attribute of a record type's validator: the (field, value)s that passed."""
_POSITIONS = "_fastcs_ethercat_positions"
"""Attribute of a record type's validator: field name -> position in the walk."""
_installed = False


def install_field_memo() -> None:
    """Remember passed (field, value) checks per record type (idempotent)."""
    global _installed
    if _installed:
        return
    from epicsdbbuilder import mydbstatic
    from epicsdbbuilder.dbd import ValidateDbField

    db: Any = mydbstatic  # its functions are bound at run time (ctypes)

    walk: Callable[[Any, str, Any], None] = ValidateDbField.ValidFieldValue

    def on_field(self: Any, name: str) -> bool:
        """Put the validator's cursor on field `name` by its position."""
        positions: dict[str, int] | None = self.__dict__.get(_POSITIONS)
        if positions is None:
            fields = self.dbEntry.iterate_fields()
            positions = {field: index for index, field in enumerate(fields)}
            self.__dict__[_POSITIONS] = positions
        position = positions.get(name)
        if position is None:
            return False
        status = db.dbFirstField(self.dbEntry, 0)
        for _ in range(position):
            status = db.dbNextField(self.dbEntry, 0)
        return status == 0

    def valid_field_value(self: Any, name: str, value: Any) -> None:
        """epicsdbbuilder's check, once per (field, value) of a record type."""
        key = (name, str(value))
        known: set[tuple[str, str]] = self.__dict__.setdefault(_PASSED, set())
        if key in known:
            return
        self.ValidFieldName(name)
        if not on_field(self, name) or db.dbVerify(self.dbEntry, key[1]):
            walk(self, name, value)  # the library's own check raises its error
        known.add(key)

    ValidateDbField.ValidFieldValue = valid_field_value
    _installed = True
