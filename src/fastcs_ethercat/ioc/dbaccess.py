"""EPICS base's database access for the IOC's own records, through the C
functions EPICS documents for device support and tools (dbAccess.h,
dbAddr.h, dbLock.h, recGbl.h, dbEvent.h), called with ctypes on the dbCore
library epicscorelibs ships (and softioc has loaded).

- `dbNameToAddr`: a record field's address (`DbAddr`), found once;
- `dbPutField`: a value into a field. A process-passive field (the VAL of an
  input) of a Passive record processes the record, as a caput does:
  record support applies its alarm limits, deadbands and links and posts the
  monitors; the IOC's input records are such records (`ioc.database`);
- `dbProcess`: the record processed as it is (its lock held);
- `dbScanLock`/`dbScanUnlock` around `recGblSetSevrMsg` (an alarm raised for
  the next processing, as device support raises one; the highest severity
  wins), `recGblResetAlarms` (the raised alarm made current and its fields
  posted) and `db_post_events`: an alarm shown on a record that must not
  process (an output: processing writes to the PLC);
- `dbPut`: a field written without processing (an output's setpoint);
- `dbGetField`: a field as text (autosave reads operators' settings);
- before iocInit: `asSetFilename` (the ACF iocInit loads) and
  `callbackSetQueueSize`.

This module knows EPICS, not FastCS: a `Record` is one record by name.
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable
from typing import Any, Final

import numpy as np

# Database request types (dbFldTypes.h), not Channel Access's DBR numbers.
DBR_STRING: Final = 0
DBR_CHAR: Final = 1
DBR_UCHAR: Final = 2
DBR_SHORT: Final = 3
DBR_USHORT: Final = 4
DBR_LONG: Final = 5
DBR_ULONG: Final = 6
DBR_INT64: Final = 7
DBR_UINT64: Final = 8
DBR_FLOAT: Final = 9
DBR_DOUBLE: Final = 10
DBR_ENUM: Final = 11

DBE_VALUE: Final = 1
DBE_LOG: Final = 2
DBE_ALARM: Final = 4

STRING_SIZE: Final = 40
"""MAX_STRING_SIZE: a DBR_STRING is 40 bytes with its NUL."""

DBR_OF_DTYPE: Final = {
    np.dtype(np.float64): DBR_DOUBLE,
    np.dtype(np.float32): DBR_FLOAT,
    np.dtype(np.int64): DBR_INT64,
    np.dtype(np.uint64): DBR_UINT64,
    np.dtype(np.int32): DBR_LONG,
    np.dtype(np.uint32): DBR_ULONG,
    np.dtype(np.int16): DBR_SHORT,
    np.dtype(np.uint16): DBR_USHORT,
    np.dtype(np.int8): DBR_CHAR,
    np.dtype(np.uint8): DBR_UCHAR,
    np.dtype(np.bool_): DBR_UCHAR,
}
"""An array's request type by its element type (little-endian, native)."""


class DbAccessError(RuntimeError):
    """EPICS refused a database access: the record or field, and the status."""


class DbAddr(ctypes.Structure):
    """`struct dbAddr` (dbAddr.h): where a record field lives."""

    _fields_ = (
        ("precord", ctypes.c_void_p),
        ("pfield", ctypes.c_void_p),
        ("pfldDes", ctypes.c_void_p),
        ("no_elements", ctypes.c_long),
        ("field_type", ctypes.c_short),
        ("field_size", ctypes.c_short),
        ("special", ctypes.c_short),
        ("dbr_field_type", ctypes.c_short),
    )


class _Library:
    """The dbCore functions used here, declared on a handle of our own."""

    def __init__(self) -> None:
        from epicscorelibs.path import get_lib

        lib = ctypes.CDLL(get_lib("dbCore"))
        pointer, buffer = ctypes.c_void_p, ctypes.c_void_p
        address = ctypes.POINTER(DbAddr)

        def declare(name: str, result: Any, *arguments: Any) -> Any:
            function = lib[name]  # a new function object: nobody else's
            function.restype = result
            function.argtypes = arguments
            return function

        self.name_to_addr = declare(
            "dbNameToAddr", ctypes.c_long, ctypes.c_char_p, address
        )
        self.put_field = declare(
            "dbPutField", ctypes.c_long, address, ctypes.c_short, buffer, ctypes.c_long
        )
        self.put = declare(
            "dbPut", ctypes.c_long, address, ctypes.c_short, buffer, ctypes.c_long
        )
        # the hot path's put: no argtypes, so ctypes converts nothing; every
        # argument is passed as the C object it is (`writer_of`)
        self.put_field_as_is = lib["dbPutField"]
        self.put_field_as_is.restype = ctypes.c_long
        self.get_field = declare(
            "dbGetField",
            ctypes.c_long,
            address,
            ctypes.c_short,
            buffer,
            ctypes.c_void_p,
            ctypes.POINTER(ctypes.c_long),
            ctypes.c_void_p,
        )
        self.process = declare("dbProcess", ctypes.c_long, pointer)
        self.lock = declare("dbScanLock", None, pointer)
        self.unlock = declare("dbScanUnlock", None, pointer)
        self.reset_alarms = declare("recGblResetAlarms", ctypes.c_ushort, pointer)
        self.time_stamp = declare("recGblGetTimeStamp", None, pointer)
        self.post_events = declare(
            "db_post_events", ctypes.c_int, pointer, pointer, ctypes.c_uint
        )
        self.set_access_file = declare("asSetFilename", ctypes.c_int, ctypes.c_char_p)
        self.set_queue_size = declare(
            "callbackSetQueueSize", ctypes.c_int, ctypes.c_int
        )
        # variadic (fmt, ...): the fixed part declared, the rest passed typed
        self.set_severity = lib["recGblSetSevrMsg"]
        self.set_severity.restype = ctypes.c_int


@functools.cache
def _library() -> _Library:
    """Loaded at the first access: only an IOC process needs EPICS."""
    return _Library()


_serving = False
"""iocInit has returned: records can be found, locked and processed (not
before: they have no lock set yet)."""


def database_serves() -> None:
    """Say that iocInit has returned."""
    global _serving
    _serving = True


def is_serving() -> bool:
    return _serving


def set_access_security_file(path: str) -> bool:
    """`asSetFilename`: iocInit loads this ACF; whether EPICS accepted it."""
    return _library().set_access_file(path.encode()) == 0


def set_callback_queue_size(entries: int) -> None:
    """`callbackSetQueueSize`, before iocInit: entries of each callback queue."""
    _library().set_queue_size(entries)


def address(name: str) -> DbAddr:
    """The address of `name` (`record` or `record.FIELD`); DbAccessError if
    the database has no such record or field, or does not serve yet."""
    if not _serving:
        raise DbAccessError(f"{name}: the database does not serve yet")
    found = DbAddr()
    status = _library().name_to_addr(name.encode(), ctypes.byref(found))
    if status:
        raise DbAccessError(f"{name}: no such record or field (status {status})")
    return found


Writer = Callable[[Any], None]
"""Puts one value into a record field (processing the record if the field
says so); raises `DbAccessError` if EPICS refuses it."""


class Record:
    """One record of the running database, by name."""

    __slots__ = ("_locked", "_record", "name", "pointer", "value_field")

    def __init__(self, name: str) -> None:
        self.name = name
        self.value_field = address(name)
        """Its VAL (the field the record's name means)."""
        self.pointer = int(self.value_field.precord or 0)
        """The record (`dbCommon *`), for the calls that take it."""
        self._record = ctypes.c_void_p(self.pointer)
        self._locked = _Locked(self.pointer)

    def writer(self, kind: str, length: int = 0) -> Writer:
        """A writer of values of `kind` into VAL (see `writer_of`)."""
        return writer_of(self.name, self.value_field, kind, length)

    def process(self) -> None:
        """Process the record as it is (`dbProcess`, with its lock held)."""
        lib = _library()
        with self.locked():
            _check(lib.process(self.pointer), self.name)

    def raise_alarm(self, severity: int, status: int, message: str = "") -> None:
        """Raise this alarm for the record's next processing (the highest
        severity raised before it wins). Call with the record locked."""
        if message:
            _library().set_severity(
                self._record,
                ctypes.c_ushort(status),
                ctypes.c_ushort(severity),
                _FORMAT,
                ctypes.c_char_p(message.encode(errors="replace")[:39]),
            )
        else:
            _library().set_severity(
                self._record, ctypes.c_ushort(status), ctypes.c_ushort(severity), None
            )

    def locked(self) -> _Locked:
        """`with record.locked():` the record's lock set held (EPICS locks
        are recursive: a put in the block takes it again)."""
        return self._locked

    def hold(self) -> Callable[[], None]:
        """Lock the record's lock set now; the call that unlocks it (once)."""
        lib = _library()
        lib.lock(self.pointer)
        held = [True]

        def release() -> None:
            if held:
                held.clear()
                lib.unlock(self.pointer)

        return release

    def show_alarm(self, severity: int, status: int, message: str = "") -> None:
        """Make this alarm the record's current one without processing it:
        raised, made current (`recGblResetAlarms`, which posts SEVR/STAT)
        and posted with VAL to monitors, the time taken now. While the
        record is active (a put under way), only raised: the put's
        completion makes it current."""
        lib = _library()
        with self.locked():
            if severity:
                self.raise_alarm(severity, status, message)
            if self.active():
                return
            lib.time_stamp(self.pointer)
            changed = lib.reset_alarms(self.pointer)
            if changed:
                lib.post_events(self.pointer, self.value_field.pfield, changed)

    def show_value(self, kind: str, value: Any, length: int = 0) -> None:
        """Write VAL without processing (an output's setpoint: processing
        would write to the PLC) and post it to monitors."""
        lib = _library()
        buffer, count, dbr = pack(kind, value, length)
        with self.locked():
            _check(
                lib.put(ctypes.byref(self.value_field), dbr, buffer, count), self.name
            )
            lib.post_events(self.pointer, self.value_field.pfield, DBE_VALUE | DBE_LOG)

    def active(self) -> bool:
        """PACT: the record is being processed (an asynchronous put)."""
        return get_text(f"{self.name}.PACT") not in ("0", "")


_FORMAT: Final = ctypes.c_char_p(b"%s")


class _Locked:
    __slots__ = ("_pointer",)

    def __init__(self, pointer: int) -> None:
        self._pointer = pointer

    def __enter__(self) -> None:
        _library().lock(self._pointer)

    def __exit__(self, *_: object) -> None:
        _library().unlock(self._pointer)


def get_text(name: str) -> str:
    """A field as EPICS converts it to text (DBR_STRING), e.g. `rec.HIHI`."""
    field = address(name)
    text = ctypes.create_string_buffer(STRING_SIZE)
    count = ctypes.c_long(1)
    status = _library().get_field(
        ctypes.byref(field), DBR_STRING, text, None, ctypes.byref(count), None
    )
    _check(status, name)
    return text.value.decode(errors="replace")


def _check(status: int, name: str) -> None:
    if status:
        raise DbAccessError(f"{name}: EPICS refused the access (status {status})")


# -- values into fields ---------------------------------------------------------------


SCALARS: Final = {
    "double": (ctypes.c_double, DBR_DOUBLE),
    "long": (ctypes.c_int32, DBR_LONG),
    "int64": (ctypes.c_int64, DBR_INT64),
    "enum": (ctypes.c_uint16, DBR_ENUM),
}
"""A scalar kind -> its C type and request type."""
KINDS: Final = (*SCALARS, "text", "array")
"""What a writer takes: a scalar kind, `text` (a str into a char array) or
`array` (a numpy array, its request type from its element type)."""


def writer_of(name: str, field: DbAddr, kind: str, length: int = 0) -> Writer:
    """A writer into `field`: one ctypes call per value for scalars.

    `length`: the elements the field holds (text and arrays are cut to it).
    """
    put = _library().put_field
    where = ctypes.byref(field)
    if kind in SCALARS:
        ctype, dbr = SCALARS[kind]
        cell = ctype()
        reference = ctypes.byref(cell)
        put_as_is = _library().put_field_as_is
        request, one = ctypes.c_short(dbr), ctypes.c_long(1)

        def write_scalar(value: Any) -> None:
            cell.value = value
            if put_as_is(where, request, reference, one):
                raise DbAccessError(f"{name}: EPICS refused {value!r}")

        return write_scalar

    def write_other(value: Any) -> None:
        buffer, count, dbr = pack(kind, value, length)
        if put(where, dbr, buffer, count):
            raise DbAccessError(f"{name}: EPICS refused {value!r}")

    return write_other


def pack(kind: str, value: Any, length: int) -> tuple[Any, int, int]:
    """(buffer, count, request type) of `value` as `kind`."""
    if kind in SCALARS:
        ctype, dbr = SCALARS[kind]
        return ctypes.byref(ctype(value)), 1, dbr
    if kind == "text":
        data = str(value).encode(errors="replace")
        if length:
            data = data[: length - 1]
        data += b"\0"
        return ctypes.create_string_buffer(data, len(data)), len(data), DBR_CHAR
    if kind == "array":
        array = np.ascontiguousarray(value)
        if length:
            array = array[:length]
        dbr = DBR_OF_DTYPE.get(array.dtype)
        if dbr is None:
            array, dbr = array.astype(np.float64), DBR_DOUBLE
        if array.dtype == np.bool_:
            array = array.astype(np.uint8)
        return array.ctypes.data_as(ctypes.c_void_p), max(len(array), 0), dbr
    raise ValueError(f"no such value kind: {kind}")
