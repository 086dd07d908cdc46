"""What FastCS 0.14.4, softioc 4.7 and epicsdbbuilder 1.5 do not offer yet.

The only module of the project that touches their internals. Delete it piece
by piece as releases catch up; the IOC calls nothing of theirs private
anywhere else.

- **Updates with a timestamp and an alarm.** `AttrR.update(value)` lets each
  transport stamp the value with the time its callback runs, has no alarm,
  and costs ~120 µs (two tasks, reprs for its tracer). A poll cycle's values
  were all read by one ADS request and must carry that request's time, and a
  cycle of thousands of changes must not cost a core. `Endpoints.publish`
  takes an `Update(value, timestamp, severity)` shaped like the one FastCS's
  main branch has, sets what `update()` would set (`_value`, the
  `_on_update_events`, an `AttrRW`'s first setpoint sync) and posts straight
  to the CA in record and the PVA read PV; `Endpoints.publish_alarm` gives the
  PVs an alarm with their value unchanged. When FastCS releases `Update`,
  both become `attribute.update(Update(...))`.
- **Where an attribute is served.** CA records are found by their PV names
  with softioc's `LookupRecord` (public). The PVA SharedPVs are kept by
  FastCS only in the closures of the callbacks its PVA transport registers on
  the attribute (`make_shared_read_pv.<locals>.set_readback`, cell
  `shared_pv`; `make_shared_write_pv.<locals>.set_setpoint`), so they are
  read from there.
- **CA out-record alarms.** softioc can stage an out record's alarm only for
  its next processing, and processing an out record of FastCS writes to the
  device: `_set_out_record_alarm` does what processing would through EPICS's
  own database calls, or, while a put is still processing the record, stages
  the alarm for the put's completion (which would otherwise overwrite it).
- **Setpoints after a put.** FastCS's CA put handler stages MAJOR on a failed
  put and NO_ALARM on a good one, just before the put completes for the
  client; `watch_ca_puts` runs the IOC's own verdict after it, before the
  completion, so `caput -c` sees the IOC's alarm every time. `sync_setpoint`
  shows a value on every setpoint PV (FastCS's sync-setpoint callbacks), so a
  put on CA shows on PVA and the other way round.
- **A poll cycle's records in one turn.** softioc's `set()` queues an in
  record's processing with `scanIoRequest` through ctypes, which releases the
  GIL: the EPICS callback thread wakes, takes the GIL for softioc's Python
  device support, and the caller waits for it back, for every record.
  `_in_record_setter` stores the value as `set()` does and queues the same
  request through a `PyDLL` binding that keeps the GIL (scanIoRequest only
  appends to a queue), so a cycle costs a third of the CPU per value.
- **The .db text at C speed.** `install_quick_db_text`: a value with nothing
  to escape is quoted without epicsdbbuilder's call per character, and a
  record's lines are written at once, not by a `print` each.
- **Record field checks once per (field, value).** epicsdbbuilder checks every
  field of every record (~0.3 ms a record, seconds for a rack);
  `install_field_memo` replaces `ValidateDbField.ValidFieldValue` with one
  that remembers what passed per record type and falls back to the library's
  own check, so its error is the library's.
- **iocInit in a worker thread.** EPICS base's `iocBuild` sleeps a fixed
  0.5 s; FastCS runs iocInit on the event loop. `ca_transport` runs it in a
  thread (a ctypes call: the GIL is released while EPICS sleeps) and
  `pva_transport` builds the PVA PVs meanwhile, once iocInit calls Python no
  more before its sleep (every record initialised and the last I/O Intr
  record's scan list made: `watch_records_initialised`; Python on the loop
  before that made each of those calls wait for the GIL and the sleep start
  late); `ca_initialised()` is awaited before anything touches the records
  or says the IOC serves.
  The in records of numbers are not processed at init (PINI): softioc's
  processing runs Python per record after the sleep, in iocInit's thread,
  waiting for the GIL the PVA build holds; `_write_initial_values` gives
  them the same value, time and alarm directly during the sleep.
- **Type hints and members once per controller class.** FastCS resolves a
  controller class's type hints twice for every instance and walks its
  members once; `install_type_hint_memo` and `install_bind_memo` do each
  once per class.
- **PVA scalar types once per kind.** FastCS builds a new p4p type for every
  PV and again for its first value; `install_p4p_type_memo` builds each
  scalar kind (datatype class, read/write) once, as the types are immutable.
- **Lean imports.** `fastcs.transports` imports every transport installed
  (REST, GraphQL, Tango too), and setuptools_dso learns its caller with
  `inspect.stack()`; `import_ioc_modules` leaves the unused transports out and
  swaps setuptools_dso's `_auto_pkg` for a frame lookup, only while importing.

`check_installed()` runs at every IOC start: each package's version must be
one this was tested with and every internal used here must exist, else the
IOC stops with one line naming the package and version.
"""

from __future__ import annotations

import asyncio
import ctypes
import enum
import functools
import importlib
import importlib.abc
import importlib.metadata
import importlib.util
import inspect
import re
import sys
import time
import types
from collections.abc import (
    Awaitable,
    Callable,
    Iterable,
    Iterator,
    Mapping,
    Sequence,
)
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.machinery import ModuleSpec
from typing import TYPE_CHECKING, Any, Final, NamedTuple

import numpy as np

from fastcs_ethercat.errors import UserError

if TYPE_CHECKING:  # FastCS is imported the lean way (`import_ioc_modules`)
    from fastcs.attributes import Attribute, AttrR
    from fastcs.transports import Transport

TESTED: Final = {
    "fastcs": ((0, 14, 4), (0, 15)),
    "softioc": ((4, 7), (4, 8)),
    "epicsdbbuilder": ((1, 5), (1, 6)),
}
"""Package -> (lowest tested version, first version not tested), as in
pyproject.toml."""


# -- the update FastCS's main branch has -------------------------------------


class Update(NamedTuple):
    """A value with the time it was read and its alarm (EPICS numbers).

    A tuple: one is made for every published value, so it must be cheap.
    """

    value: Any
    timestamp: float
    severity: int = 0
    status: int = 0
    message: str = ""


def pva_time(stamp: float) -> dict[str, int]:
    """The PVA timeStamp fields of a time.time() value."""
    seconds = int(stamp)
    return {"secondsPastEpoch": seconds, "nanoseconds": int((stamp - seconds) * 1e9)}


# -- where an attribute is served --------------------------------------------


@dataclass(frozen=True)
class _Closure:
    """One FastCS callback whose closure holds a PVA SharedPV."""

    module: str
    outer: str
    inner: str
    cell: str

    @property
    def qualname(self) -> str:
        return f"{self.outer}.<locals>.{self.inner}"


_CA_MODULE: Final = "fastcs.transports.epics.ca.ioc"
_PVA_IOC_MODULE: Final = "fastcs.transports.epics.pva.ioc"
"""Where FastCS's PVA transport makes its PVs (`make_shared_read_pv`)."""
_PVA_MODULE: Final = "fastcs.transports.epics.pva._pv_handlers"
_PVA_TYPES_MODULE: Final = "fastcs.transports.epics.pva.types"
CA_READ: Final = _Closure(
    _CA_MODULE, "_create_and_link_read_pv", "async_record_set", "record"
)
"""The CA transport's on-update callback (recognised, its record found by name)."""
PVA_READ: Final = _Closure(
    _PVA_MODULE, "make_shared_read_pv", "set_readback", "shared_pv"
)
PVA_WRITE: Final = _Closure(
    _PVA_MODULE, "make_shared_write_pv", "set_setpoint", "shared_pv"
)
CA_WRITE: Final = _Closure(
    _CA_MODULE, "_create_and_link_write_pv", "set_setpoint_without_process", "record"
)
"""The CA transport's sync-setpoint callback (shape check only)."""
RBV_SUFFIX: Final = "_RBV"
_NO_ALARM: Final = {"severity": 0, "status": 0, "message": ""}
_ON_UPDATE: Final = "_ProcessDeviceSupportOut__on_update"
"""Where a softioc out record keeps its on-update callback."""
_WATCHED: Final = "_fastcs_ethercat_watched"
"""Set on an out record whose puts `watch_ca_puts` follows."""


class Parts(enum.IntFlag):
    """Which PVs of an attribute an alarm goes to."""

    CA_IN = enum.auto()
    PVA_READ = enum.auto()
    CA_OUT = enum.auto()
    PVA_WRITE = enum.auto()
    READBACK = CA_IN | PVA_READ
    """What the PLC holds: the in record (`_RBV` of an output) and its PVA PV."""
    SETPOINT = CA_OUT | PVA_WRITE
    """What was asked for: an output's out record and PVA setpoint PV."""
    ALL = READBACK | SETPOINT


def ca_name(attribute: Attribute[Any, Any]) -> str:
    """The CA PV FastCS makes for `attribute` (an `AttrRW`'s setpoint)."""
    from fastcs.transports.epics.util import pv_prefix_from_path
    from fastcs.util import snake_to_pascal

    return f"{pv_prefix_from_path(attribute.path)}:{snake_to_pascal(attribute.name)}"


def _ca_names(attribute: Attribute[Any, Any], *, reads: bool) -> list[str]:
    """CA records of `attribute`: the out record, and the in record if `reads`."""
    from fastcs.attributes import AttrR, AttrW

    name = ca_name(attribute) if attribute.path else ""
    if not name:
        return []
    found = [name] if isinstance(attribute, AttrW) else []
    if reads and isinstance(attribute, AttrR):
        found.append(name + RBV_SUFFIX if isinstance(attribute, AttrW) else name)
    return found


def database_records(attribute: Attribute[Any, Any], *, reads: bool) -> list[Any]:
    """The CA database records (epicsdbbuilder) of `attribute`'s out record,
    and in record if `reads`, to set fields on between the CA transport's
    connect and iocInit."""
    from epicsdbbuilder import LookupRecord

    found = []
    for name in _ca_names(attribute, reads=reads):
        try:
            found.append(LookupRecord(name))
        except KeyError:
            continue
    return found


def _ca_record(name: str) -> Any:
    """softioc's record `name` (its device support), None without one."""
    if "softioc.device_core" not in sys.modules:  # CA not served
        return None
    from softioc.device_core import LookupRecord

    try:
        return LookupRecord(name)
    except KeyError:
        return None


@dataclass(frozen=True)
class Endpoints:
    """The CA records and PVA PVs serving one attribute (None: not made).

    `ca_in`/`ca_out` are softioc device supports, `pva_read`/`pva_write`
    p4p SharedPVs; `others` every other on-update callback (anyone's), which
    gets each value as from `update()`.
    """

    attribute: Attribute[Any, Any]
    ca_in: Any = None
    ca_out: Any = None
    pva_read: Any = None
    pva_write: Any = None
    others: tuple[Callable[[Any], Any], ...] = ()

    def __bool__(self) -> bool:
        return any(
            x is not None
            for x in (self.ca_in, self.ca_out, self.pva_read, self.pva_write)
        )

    def publish_alarm(
        self, severity: int, status: int, message: str, parts: Parts = Parts.ALL
    ) -> int:
        """Give the PVs of `parts` this alarm, value unchanged; how many were
        reached."""
        reached = 0
        if self.ca_in is not None and Parts.CA_IN in parts:
            # the time too: the record is on device time
            self.ca_in.set_alarm(severity, status, timestamp=time.time())
            reached += 1
        if self.ca_out is not None and Parts.CA_OUT in parts:
            _set_out_record_alarm(self.ca_out, severity, status)
            reached += 1
        for pv, part in (
            (self.pva_read, Parts.PVA_READ),
            (self.pva_write, Parts.PVA_WRITE),
        ):
            if pv is not None and part in parts:
                _post_pva_alarm(pv, severity, pva_status(status), message)
                reached += 1
        return reached


def endpoints_of(attribute: Attribute[Any, Any]) -> Endpoints:
    """Where FastCS serves `attribute` so far (transports connected/serving)."""
    from fastcs.attributes import AttrR, AttrW

    read_callbacks: list[Callable[..., Any]] = []
    write_callbacks: Iterable[Callable[..., Any]] = ()
    if isinstance(attribute, AttrR):
        read_callbacks = [cb for cb, _ in attribute._on_update_callbacks or ()]  # pyright: ignore[reportPrivateUsage]
    if isinstance(attribute, AttrW):
        write_callbacks = attribute._sync_setpoint_callbacks  # pyright: ignore[reportPrivateUsage]
    names = _ca_names(attribute, reads=True)
    ca_out = _ca_record(names[0]) if names and isinstance(attribute, AttrW) else None
    ca_in = _ca_record(names[-1]) if names and isinstance(attribute, AttrR) else None
    others = tuple(
        cb for cb in read_callbacks if not (_is(cb, CA_READ) or _is(cb, PVA_READ))
    )
    return Endpoints(
        attribute,
        ca_in=ca_in,
        ca_out=ca_out,
        pva_read=_find(read_callbacks, PVA_READ),
        pva_write=_find(write_callbacks, PVA_WRITE),
        others=others,
    )


def _find(callbacks: Iterable[Callable[..., Any]], closure: _Closure) -> Any:
    for callback in callbacks:
        if _is(callback, closure):
            code: types.CodeType = callback.__code__  # type: ignore[attr-defined]
            cells = callback.__closure__ or ()  # type: ignore[attr-defined]
            return cells[code.co_freevars.index(closure.cell)].cell_contents
    return None


def _is(callback: Callable[..., Any], closure: _Closure) -> bool:
    return (
        getattr(callback, "__module__", None) == closure.module
        and getattr(callback, "__qualname__", None) == closure.qualname
    )


# -- publishing values ---------------------------------------------------------


class ValueRoute:
    """Publishes `Update`s of one attribute, once the transports serve.

    `post` does it synchronously into a `CycleWrites` (one poll cycle's CA
    writes, made under one lock) and returns what must still be awaited: the
    first setpoint sync of an `AttrRW`, and on-update callbacks of anyone
    else, as `update()` would call them; None almost always.
    """

    def __init__(self, attribute: AttrR[Any, Any]) -> None:
        from fastcs.attributes import AttrRW
        from fastcs.transports.epics.ca.util import cast_to_epics_type

        self.attribute = attribute
        self.endpoints = endpoints_of(attribute)
        self._writable = isinstance(attribute, AttrRW)
        self._to_epics = cast_to_epics_type
        self._in_record: _InRecord | None = None
        self._set_ca: Callable[[Any, Update], None] | None = None
        self._pva: Callable[[Update], None] | None = None
        pv = self.endpoints.pva_read
        if pv is not None:
            read_pv = _ReadPv.of(pv)
            self._pva = read_pv.post if read_pv else _pva_poster(pv.post, attribute)
        device = self.endpoints.ca_in
        if device is not None:
            self._in_record = _InRecord.of(device, attribute.datatype)
            if self._in_record is None:  # text, arrays: softioc processes them
                self._set_ca = _in_record_setter(device)
            else:
                _use_device_time(device)

    def post(self, update: Update, writes: CycleWrites) -> Awaitable[None] | None:
        """What `attribute.update(update)` will do: value, posts, setpoint."""
        attribute, value = self.attribute, update.value
        attribute._value = value  # pyright: ignore[reportPrivateUsage]
        events = attribute._on_update_events  # pyright: ignore[reportPrivateUsage]
        if events:
            attribute._on_update_events = {e for e in events if not e.set(value)}  # pyright: ignore[reportPrivateUsage]
        if self._in_record is not None:
            writes.add(self._in_record, update)
        elif self._set_ca is not None:
            self._set_ca(self._to_epics(attribute.datatype, value), update)
        if self._pva is not None:
            self._pva(update)
        if self.endpoints.others or (
            self._writable and not attribute._setpoint_initialised  # pyright: ignore[reportAttributeAccessIssue]
        ):
            return self._callbacks(value)
        return None

    async def _callbacks(self, value: Any) -> None:
        attribute: Any = self.attribute
        if self._writable and not attribute._setpoint_initialised:
            await attribute._call_sync_setpoint_callbacks(value)
            attribute._setpoint_initialised = True
        for callback in self.endpoints.others:
            await callback(value)

    async def publish(self, update: Update) -> None:
        """`post` one update on its own."""
        writes = CycleWrites(update.timestamp)
        pending = self.post(update, writes)
        writes.flush()
        if pending is not None:
            await pending


class CycleWrites:
    """The CA in-record writes of one poll cycle.

    `flush` locks every record of the cycle at once (dbScanLockMany, which
    waits without the GIL), writes each one's VAL, TIME and alarm and posts
    its monitors, then unlocks: per record only EPICS's C code runs, no
    Python device support, and no EPICS thread waits for the GIL meanwhile.
    """

    def __init__(self, stamp: float) -> None:
        self.stamp = stamp
        seconds = int(stamp)
        self.packed_time = (seconds - _EPICS_EPOCH) | (
            int((stamp - seconds) * 1e9) << 32
        )
        self.records: list[_InRecord] = []
        self.updates: list[Update] = []

    def add(self, record: _InRecord, update: Update) -> None:
        self.records.append(record)
        self.updates.append(update)

    def flush(self) -> None:
        if not self.records:
            return
        functions = _database_functions()
        records, self.records = self.records, []
        updates, self.updates = self.updates, []
        addresses = (ctypes.c_void_p * len(records))(*[r.address for r in records])
        locker = functions.locker_alloc(addresses, len(records), 0)
        if not locker:
            raise MemoryError("dbLockerAlloc failed")
        functions.lock_many(locker)
        try:
            packed_time, post = self.packed_time, functions.post_events
            for record, update in zip(records, updates, strict=True):
                record.write(update, packed_time, post)
        finally:
            functions.unlock_many(locker)
            functions.locker_free(locker)


_EPICS_EPOCH: Final = 631152000
"""POSIX seconds at the EPICS epoch (1990-01-01), as epicsTimeStamp counts."""
_DBE_VALUE_LOG: Final = 1 | 4
"""DBE_VALUE | DBE_LOG: what a record posts for a new value (no deadband)."""
_INVALID: Final = 3
_UDF: Final = 17
_DIRECT_VALUE_TYPES: Final = (
    ctypes.c_double,  # ai
    ctypes.c_int32,  # longin
    ctypes.c_uint16,  # bi, mbbi
    ctypes.c_int64,  # int64in
)
"""softioc value types of in records whose VAL is written directly."""


class _InRecord:
    """A softioc in record whose VAL, TIME and alarm are written directly.

    Only records whose value is one number (ai, longin, bi, mbbi, int64in).
    softioc's own `_value` holds a value object this updates in place and no
    timestamp, so a processing softioc does later (a client's PROC, an
    alarm) writes the same value and keeps the record's time.
    """

    __slots__ = (
        "address",
        "device",
        "epics_value",
        "is_float",
        "new_severity",
        "new_status",
        "severity",
        "status",
        "time",
        "to_record",
        "udf",
        "value",
        "value_address",
    )

    def __init__(
        self,
        device: Any,
        fields: Any,
        value_type: Any,
        to_record: Callable[[Any], Any] | None,
    ) -> None:
        base: int = fields.record.value
        offsets = fields.fields
        self.device = device
        self.address = base
        self.value_address = base + offsets["VAL"][0]
        self.value = value_type.from_address(self.value_address)
        self.time = ctypes.c_uint64.from_address(base + offsets["TIME"][0])
        self.udf = ctypes.c_uint8.from_address(base + offsets["UDF"][0])
        self.severity = ctypes.c_uint16.from_address(base + offsets["SEVR"][0])
        self.status = ctypes.c_uint16.from_address(base + offsets["STAT"][0])
        self.new_severity = ctypes.c_uint16.from_address(base + offsets["NSEV"][0])
        self.new_status = ctypes.c_uint16.from_address(base + offsets["NSTA"][0])
        self.is_float = value_type is ctypes.c_double
        self.to_record = to_record
        self.epics_value = value_type(device._value[0].value)
        device._value = (self.epics_value, *device._value[1:3], None)

    @classmethod
    def of(cls, device: Any, datatype: Any) -> _InRecord | None:
        """The direct view of `device`'s record, None if it is not a number."""
        from fastcs.datatypes import Enum
        from fastcs.transports.epics.ca.util import cast_to_epics_type

        fields = getattr(device, "_record", None)
        value_type: Any = getattr(device, "_ctype_", None)
        if fields is None or value_type not in _DIRECT_VALUE_TYPES:
            return None
        if fields.fields["VAL"][1] != ctypes.sizeof(value_type):
            return None
        to_record = None
        if isinstance(datatype, Enum):  # the record holds the member's index
            to_record = functools.partial(cast_to_epics_type, datatype)
        return cls(device, fields, value_type, to_record)

    def write(self, update: Update, packed_time: int, post: Any) -> None:
        """Under the record's lock: VAL, TIME, alarm, monitors."""
        value = update.value
        if self.to_record is not None:
            value = self.to_record(value)
        severity, status = update.severity, update.status
        if self.is_float and value != value:  # NaN: UDF, as an ai record does
            severity, status = _INVALID, _UDF
            self.udf.value = 1
        else:
            self.udf.value = 0
        self.epics_value.value = value
        self.value.value = value
        self.time.value = packed_time
        mask = _DBE_VALUE_LOG
        if self.severity.value != severity or self.status.value != status:
            mask |= self._alarm(severity, status)
        post(self.address, self.value_address, mask)

    def _alarm(self, severity: int, status: int) -> int:
        """Make (severity, status) the record's alarm; the monitor mask.

        NSEV/NSTA through views made once: softioc's field setter costs a
        ctypes cast per write, and a status bit's alarm may change every cycle.
        """
        self.device._value = (self.epics_value, severity, status, None)
        self.new_severity.value = severity
        self.new_status.value = status
        return _database_functions().reset_alarms(self.address)


# -- initial values without processing ------------------------------------------


def _direct_in_records() -> list[Any]:
    """softioc's in records whose value is one number (`_InRecord`'s kind)."""
    from softioc.device import ProcessDeviceSupportIn
    from softioc.device_core import LookupRecordList

    return [
        device
        for _, device in LookupRecordList()
        if isinstance(device, ProcessDeviceSupportIn)
        and getattr(device, "_ctype_", None) in _DIRECT_VALUE_TYPES
    ]


def _skip_initial_processing(devices: Iterable[Any]) -> None:
    """No PINI for these records (before iocInit): `_write_initial_values`
    gives them what processing would, without Python per record. The field
    is left out (its default is NO): one line less per record to write and
    parse."""
    from epicsdbbuilder import LookupRecord

    for device in devices:
        LookupRecord(device._name).PINI = None


def _write_initial_values(devices: Iterable[Any]) -> int:
    """What PINI processing gives an in record, written directly: its value,
    UDF, the time now and its staged alarm (NO_ALARM unless set), all under
    one lock. softioc's processing calls Python for every record, in
    iocInit's thread after EPICS's sleep, where it waits for the GIL that
    the PVA build holds; this runs on the event loop during the sleep.
    Returns how many were written."""
    writes = CycleWrites(time.time())
    for device in devices:
        record = _InRecord.of(device, None)
        if record is None:  # no record fields: not initialised by EPICS
            continue
        value, severity, status = device._value[:3]
        writes.add(record, Update(value.value, writes.stamp, severity, status))
    written = len(writes.records)
    writes.flush()
    return written


_READ_PV: Final = "_fastcs_ethercat_read_pv"
"""Attribute of a FastCS PVA read PV: its `_ReadPv`."""


class _ReadPv:
    """A FastCS PVA read PV that the poll cycles post to only while a client
    is connected.

    p4p's post copies a value into pvxs even when nobody listens (~5 µs a
    value, most of a core for a rack whose values all change). While no
    channel is open, a cycle's update only waits here. The first connection
    posts it before pvxs serves the channel (pvxs calls back on its own
    thread, before it answers), so a get or a monitor never sees an older
    value; any other post (FastCS's own, an alarm) posts it first too.
    Attached when FastCS makes the PV (`_make_read_pvs_lazy`), so no
    connection is missed.

    No lock (a post can wait on pvxs's thread): the connecting thread's post
    may cross one of the event loop's, so each post counts itself, and a
    post that another crossed is followed by the newest update again.
    """

    def __init__(self, pv: Any, attribute: AttrR[Any, Any]) -> None:
        self.connected = False
        self.waiting: Update | None = None
        self.newest: Update | None = None
        self.posts = 0
        raw_post = pv.post
        self._post = _pva_poster(raw_post, attribute)
        handler = pv._whandler  # p4p looks its callbacks up on every call
        first, last = handler.onFirstConnect, handler.onLastDisconnect

        def on_first_connect() -> None:
            self.connected = True
            self._catch_up()
            first()

        def on_last_disconnect() -> None:
            self.connected = False
            last()

        def post_now(value: Any, **kws: Any) -> None:
            self._catch_up()
            self.newest = None  # ours is older than this one
            raw_post(value, **kws)

        handler.onFirstConnect = on_first_connect
        handler.onLastDisconnect = on_last_disconnect
        pv.post = post_now
        pv.__dict__[_READ_PV] = self

    @staticmethod
    def of(pv: Any) -> _ReadPv | None:
        return pv.__dict__.get(_READ_PV)

    def post(self, update: Update) -> None:
        """A poll cycle's update: posted now if a client is connected."""
        self.newest = update
        if self.connected:
            self.waiting = None
            self.posts += 1
            self._post(update)
        else:
            self.waiting = update

    def _catch_up(self) -> None:
        """Post the waiting update, and the newest again if a post crossed."""
        update, self.waiting = self.waiting, None
        while update is not None:
            before = self.posts = self.posts + 1
            self._post(update)
            if self.posts == before:
                return
            update = self.newest


def _make_read_pvs_lazy() -> None:
    """Every PVA read PV FastCS makes from now on gets its `_ReadPv`."""
    module: Any = importlib.import_module(_PVA_IOC_MODULE)
    make: Any = module.make_shared_read_pv
    if getattr(make, "_fastcs_ethercat", False):
        return

    def make_shared_read_pv(attribute: AttrR[Any, Any]) -> Any:
        pv = make(attribute)
        _ReadPv(pv, attribute)
        return pv

    make_shared_read_pv._fastcs_ethercat = True  # type: ignore[attr-defined]
    module.make_shared_read_pv = make_shared_read_pv


@functools.cache
def install_p4p_type_memo() -> None:
    """Build each PVA scalar type once (idempotent).

    FastCS's `make_p4p_type` builds a new p4p type for every PV, and again for
    its first value: ~4 800 builds at 104 terminals, inside the PVA build
    that must fit EPICS's 0.5 s iocInit sleep. A scalar's type depends only
    on its datatype's class and whether the attribute reads and writes, and
    a p4p `Type` is immutable, so the PVs of one kind share it. Other
    datatypes (enums, waveforms, tables) are built each time, as before.
    """
    from fastcs.attributes import AttrR, AttrW
    from fastcs.datatypes import Bool, Float, Int, String

    pva_types: Any = importlib.import_module(_PVA_TYPES_MODULE)
    handlers: Any = importlib.import_module(_PVA_MODULE)
    build: Any = getattr(pva_types, "make_p4p_type", None)
    if build is None:  # `shape_problems` says so
        return
    scalars = (Bool, Float, Int, String)
    known: dict[tuple[type, bool, bool], Any] = {}

    def make_p4p_type(attribute: Attribute[Any, Any]) -> Any:
        kind = type(attribute.datatype)
        if kind not in scalars:
            return build(attribute)
        key = (kind, isinstance(attribute, AttrR), isinstance(attribute, AttrW))
        found = known.get(key)
        if found is None:
            found = known[key] = build(attribute)
        return found

    pva_types.make_p4p_type = make_p4p_type
    handlers.make_p4p_type = make_p4p_type


def _pva_poster(
    post: Callable[..., None], attribute: AttrR[Any, Any]
) -> Callable[[Update], None]:
    """Posts an update's value, alarm and time in the form FastCS's PV takes
    (`post`: the PV's)."""
    from fastcs.datatypes import Bool, Enum, Float, Int, String, Waveform
    from fastcs.transports.epics.pva.types import cast_to_p4p_value

    def alarm_of(update: Update) -> dict[str, Any]:
        status = pva_status(update.status)
        return {
            "severity": update.severity,
            "status": status,
            "message": update.message,
        }

    def scalar(update: Update) -> None:
        alarm = alarm_of(update) if update.severity else _NO_ALARM
        post(
            {
                "value": update.value,
                "alarm": alarm,
                "timeStamp": pva_time(update.timestamp),
            }
        )

    def wrapped(update: Update) -> None:  # NTEnum, NTNDArray: p4p wraps them
        post(
            cast_to_p4p_value(attribute, update.value),
            timestamp=update.timestamp,
            severity=update.severity,
            message=update.message,
        )

    def plain(update: Update) -> None:
        post(cast_to_p4p_value(attribute, update.value))

    datatype = attribute.datatype
    if isinstance(datatype, Int | Float | Bool | String):
        return scalar
    return wrapped if isinstance(datatype, Enum | Waveform) else plain


def _post_pva_alarm(pv: Any, severity: int, status: int, message: str) -> None:
    """Post only alarm and time, so the value stays as last posted (a value
    waiting for a client is posted first: see `_ReadPv`)."""
    now = time.time()
    if isinstance(pv.current(), np.ndarray):
        # NTNDArray (a FastCS Waveform) wraps only arrays; its alarm has no status.
        pv.post(pv.current(), severity=severity, message=message, timestamp=now)
        return
    pv.post(
        {
            "alarm": {"severity": severity, "status": status, "message": message},
            "timeStamp": pva_time(now),
        }
    )


_PVA_STATUS_OF: Final = {
    **dict.fromkeys((1, 2, 3, 4, 5, 6, 7, 8, 11), 1),  # READ..COS, HWLIMIT: DEVICE
    **dict.fromkeys((9, 10, 17), 2),  # COMM, TIMEOUT, UDF: DRIVER
    **dict.fromkeys((12, 13, 14, 15, 16), 3),  # CALC..BAD_SUB: RECORD
    **dict.fromkeys((18, 19, 20, 21), 4),  # DISABLE..WRITE_ACCESS: DB
}
"""CA alarm status (menuAlarmStat) -> the PVA alarm_t status, as QSRV groups
them; 6 (UNDEFINED) for anything else but NO_ALARM."""


def pva_status(status: int) -> int:
    return 0 if status == 0 else _PVA_STATUS_OF.get(status, 6)


# -- softioc -------------------------------------------------------------------


def _use_device_time(record: Any) -> None:
    """Let `record` keep the TIME its device support sets (TSE=-2)."""
    fields = getattr(record, "_record", None)  # softioc's view of its fields
    if fields is not None:
        fields.TSE = -2


def _in_record_setter(device: Any) -> Callable[[Any, Update], None]:
    """`set(value, severity, alarm, timestamp)` of a softioc in record that
    queues its processing without releasing the GIL (see the top)."""
    to_epics = device._value_to_epics
    request = _scan_io_request_keeping_gil()
    on_device_time = False

    def set_value(value: Any, update: Update) -> None:
        nonlocal on_device_time
        if not on_device_time:  # at the first value: its PINI is done by then
            _use_device_time(device)
            on_device_time = True
        device._value = (
            to_epics(value),
            update.severity,
            update.status,
            update.timestamp,
        )
        ioscan = device._DeviceSupportCore__ioscanpvt
        if ioscan:
            request(ioscan)

    return set_value


@functools.cache
def _scan_io_request_keeping_gil() -> Any:
    from epicscorelibs.ioc import dbCore

    function = ctypes.PyDLL(dbCore._name).scanIoRequest
    function.argtypes = (ctypes.c_void_p,)
    function.restype = None
    return function


def _set_out_record_alarm(record: Any, severity: int, status: int) -> None:
    """Give a softioc out record this alarm now, value and device untouched.

    Stage the alarm as softioc does (kept for the record's next processing),
    then, under the record's lock, do what processing would: stage it in
    NSEV/NSTA, let EPICS move it to SEVR/STAT (recGblResetAlarms, which posts
    those fields) and post VAL with DBE_ALARM, so monitors see it. While a
    put is processing the record (PACT), only stage it: the put's completion
    moves it to SEVR/STAT (resetting now would let the completion clear it).
    """
    record.set(record.get(), process=False, severity=severity, alarm=status)
    fields = getattr(record, "_record", None)
    if fields is None:  # before iocInit: softioc applies the staged alarm
        return
    functions = _database_functions()
    base: int = fields.record.value
    value_address = base + fields.fields["VAL"][0]
    functions.lock(base)
    try:
        fields.NSEV = severity
        fields.NSTA = status
        if fields.PACT:
            return
        fields.TIME = time.time()
        changed = functions.reset_alarms(base)
        if changed:
            functions.post_events(base, value_address, changed)
    finally:
        functions.unlock(base)


@dataclass(frozen=True)
class _DatabaseFunctions:
    lock: Any
    unlock: Any
    reset_alarms: Any
    post_events: Any
    locker_alloc: Any
    locker_free: Any
    lock_many: Any
    unlock_many: Any


@functools.cache
def _database_functions() -> _DatabaseFunctions:
    """EPICS database calls, loaded only once a CA IOC (softioc) runs.

    Locking waits without the GIL (a record being processed may be waiting
    for it); the calls made under the lock keep it (no other thread gets a
    turn in between).
    """
    from epicscorelibs.ioc import dbCore

    keeping_gil = ctypes.PyDLL(dbCore._name)
    pointer = (ctypes.c_void_p,)
    for library, name in (
        (dbCore, "dbScanLock"),
        (dbCore, "dbScanUnlock"),
        (dbCore, "dbScanLockMany"),
        (keeping_gil, "dbScanUnlockMany"),
        (keeping_gil, "dbLockerFree"),
    ):
        getattr(library, name).argtypes = pointer
        getattr(library, name).restype = None
    locker_alloc = keeping_gil.dbLockerAlloc
    locker_alloc.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_uint)
    locker_alloc.restype = ctypes.c_void_p
    reset_alarms = keeping_gil.recGblResetAlarms
    reset_alarms.argtypes = pointer
    reset_alarms.restype = ctypes.c_ushort
    post_events = keeping_gil.db_post_events
    post_events.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint)
    post_events.restype = ctypes.c_int
    return _DatabaseFunctions(
        lock=dbCore.dbScanLock,
        unlock=dbCore.dbScanUnlock,
        reset_alarms=reset_alarms,
        post_events=post_events,
        locker_alloc=locker_alloc,
        locker_free=keeping_gil.dbLockerFree,
        lock_many=dbCore.dbScanLockMany,
        unlock_many=keeping_gil.dbScanUnlockMany,
    )


def watch_ca_puts(
    attribute: Attribute[Any, Any], after: Callable[[Attribute[Any, Any]], None]
) -> bool:
    """Call `after(attribute)` when FastCS has handled a CA put to the
    attribute's out record (and staged its own alarm), before the put
    completes for the client. Once per record; False without one."""
    record = endpoints_of(attribute).ca_out
    if record is None:
        return False
    if getattr(record, _WATCHED, False):
        return True
    handler = getattr(record, _ON_UPDATE)

    async def on_update(value: Any) -> None:
        try:
            await handler(value)
        finally:
            after(attribute)

    setattr(record, _ON_UPDATE, on_update)
    setattr(record, _WATCHED, True)
    return True


def take_over_setpoints(attribute: Attribute[Any, Any]) -> None:
    """The IOC shows this output's setpoints itself from now on
    (`ioc.setpoints`): FastCS's own sync at the first value is skipped."""
    from fastcs.attributes import AttrRW

    if isinstance(attribute, AttrRW):
        attribute._setpoint_initialised = True  # pyright: ignore[reportAttributeAccessIssue]


async def sync_setpoint(attribute: Attribute[Any, Any], value: Any) -> None:
    """Show `value` on every setpoint PV of `attribute` (CA out record
    without processing, PVA setpoint PV), as FastCS does at start."""
    from fastcs.attributes import AttrW

    if isinstance(attribute, AttrW):
        await attribute._call_sync_setpoint_callbacks(value)  # pyright: ignore[reportPrivateUsage]


def set_callback_queue_size(entries: int) -> None:
    """EPICS callback queue entries (before iocInit): every changed record
    queues one, and the default 2000 overflows on a large rack."""
    from softioc.imports import callbackSetQueueSize

    callbackSetQueueSize(entries)


_ca_initialised: asyncio.Future[None] | None = None
"""Done once this process's iocInit has returned (softioc inits once)."""
_ca_records_initialised: asyncio.Future[None] | None = None
"""Done once iocInit needs Python no more before its sleep: every record
initialised and in its scan list (see `_watch_scan_lists`)."""
_pva_built: asyncio.Future[None] | None = None
"""Done once the PVA transport has made its PVs (or failed to)."""
_HOOK_RECORDS_DONE: Final = b"initHookAfterFinishDevSup"
"""The init hook announced after every record's device support has
initialised, just before iocBuild's `scanInit` and fixed sleep."""
_init_hooks: list[Any] = []
"""The ctypes callbacks registered with EPICS (kept alive)."""
_scan_list_entries_left = 0
"""I/O Intr records `scanInit` has still to ask softioc for their scan list."""


def watch_records_initialised(loop: asyncio.AbstractEventLoop) -> asyncio.Future[None]:
    """A future that EPICS resolves once the coming iocInit needs Python no
    more before its sleep (`_ca_records_initialised`); call once the records
    exist, before iocInit."""
    global _ca_records_initialised, _scan_list_entries_left
    _scan_list_entries_left = _io_intr_records()
    _ca_records_initialised = records = loop.create_future()
    if not _init_hooks:
        _announce_records_initialised(loop)
    return records


def _announce_records_initialised(loop: asyncio.AbstractEventLoop) -> None:
    """Have EPICS resolve `_ca_records_initialised`: at the init hook after
    device support if no record waits for a scan list, else after the last
    one's (see `_watch_scan_lists`). The hook is registered with the public
    `initHookRegister`; its state found by `initHookName`, not its number."""
    from epicscorelibs.ioc import dbCore

    name_of = dbCore.initHookName
    name_of.argtypes = (ctypes.c_int,)
    name_of.restype = ctypes.c_char_p

    @ctypes.CFUNCTYPE(None, ctypes.c_int)
    def hook(state: int) -> None:
        done = _ca_records_initialised
        if done is None or name_of(state) != _HOOK_RECORDS_DONE:
            return
        if _scan_list_entries_left <= 0:
            loop.call_soon_threadsafe(_resolve, done)

    register = dbCore.initHookRegister
    register.argtypes = (ctypes.c_void_p,)
    register.restype = ctypes.c_int
    if register(ctypes.cast(hook, ctypes.c_void_p)) == 0:
        _init_hooks.append(hook)
    _watch_scan_lists(loop)


def _io_intr_records() -> int:
    """softioc's records scanned on I/O Intr (every in record by default)."""
    from epicsdbbuilder import LookupRecord
    from softioc.device_core import LookupRecordList

    def scan(name: str) -> str:
        try:
            return str(LookupRecord(name)._FieldValue("SCAN"))
        except KeyError:  # not set: the record type's default, Passive
            return "Passive"

    return sum(1 for name, _ in LookupRecordList() if scan(name) == "I/O Intr")


def _watch_scan_lists(loop: asyncio.AbstractEventLoop) -> None:
    """Resolve `_ca_records_initialised` after `scanInit` has put the last
    I/O Intr record in its scan list (once per process).

    `scanInit` asks softioc's Python device support for each such record's
    scan list (`get_ioint_info`, which calls `scanIoInit` once per record),
    in iocInit's thread, each call waiting for the GIL. Python work on the
    loop meanwhile (the PVA build) held the sleep that follows back by
    0.05-0.17 s at 104 terminals (2 224 records): it starts only after the
    last call.
    """
    from softioc import imports

    library_init: Callable[[Any], None] = imports.scanIoInit

    def scan_io_init(scan_list: Any) -> None:
        global _scan_list_entries_left
        library_init(scan_list)
        _scan_list_entries_left -= 1
        done = _ca_records_initialised
        if _scan_list_entries_left == 0 and done is not None:
            loop.call_soon_threadsafe(_resolve, done)

    imports.scanIoInit = scan_io_init


def _resolve(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


def ca_transport(aliases: Mapping[str, str]) -> Transport:
    """FastCS's CA transport, its `serve` running iocInit in a worker thread.

    EPICS base's `iocBuild` sleeps 0.5 s (a fixed `epicsThreadSleep(.5)`
    after `scanInit`), and FastCS calls iocInit on the event loop: a quarter
    of a 104-terminal start did nothing. iocInit is a ctypes call that
    releases the GIL, so in a thread the PVA transport (`pva_transport`)
    builds its PVs during the sleep, once iocInit has called Python for the
    last time before it (see `_watch_scan_lists`; before, the two would
    share the GIL and stretch the part before the sleep). Await
    `ca_initialised()` before touching the records or saying the IOC serves.
    """
    from fastcs.transports.epics import EpicsCAOptions
    from fastcs.transports.epics.ca.transport import EpicsCATransport

    class ThreadedInitCATransport(EpicsCATransport):
        direct: tuple[Any, ...] = ()
        """Its in records initialised by `_write_initial_values`."""

        def connect(
            self, controller_apis: list[Any], loop: asyncio.AbstractEventLoop
        ) -> None:
            super().connect(controller_apis, loop)
            self.direct = tuple(_direct_in_records())
            _skip_initial_processing(self.direct)

        async def serve(self) -> None:
            global _ca_initialised
            loop = asyncio.get_running_loop()
            _ca_initialised = done = loop.create_future()
            records = watch_records_initialised(loop)
            # first in line: before the PVA build that waits for it too
            records.add_done_callback(lambda _: _write_initial_values(self.direct))
            try:
                await asyncio.to_thread(self._ioc.run, self._loop)  # pyright: ignore[reportPrivateUsage]
            except BaseException as error:
                done.set_exception(error)
                _resolve(records)
                raise
            _resolve(records)
            done.set_result(None)

        def __repr__(self) -> str:
            return f"ThreadedInit{super().__repr__()}"

    return ThreadedInitCATransport(epicsca=EpicsCAOptions(aliases=dict(aliases)))


def pva_transport() -> Transport:
    """FastCS's PVA transport, building its PVs once iocInit (if CA serves)
    has initialised the records and sleeps (see `ca_transport`)."""
    from fastcs.transports.epics.pva.transport import EpicsPVATransport

    class AfterCaRecordsPVATransport(EpicsPVATransport):
        def connect(
            self, controller_apis: list[Any], loop: asyncio.AbstractEventLoop
        ) -> None:
            global _pva_built
            super().connect(controller_apis, loop)
            _pva_built = built = loop.create_future()
            ioc: Any = self._ioc  # pyright: ignore[reportPrivateUsage]
            build = ioc._build_providers

            async def build_providers() -> Any:
                try:
                    return await build()
                finally:
                    _resolve(built)

            ioc._build_providers = build_providers

        async def serve(self) -> None:
            if _ca_records_initialised is not None:
                await asyncio.shield(_ca_records_initialised)
            await super().serve()

    return AfterCaRecordsPVATransport()


async def pvs_built() -> None:
    """Once the CA records are initialised and the PVA PVs made, while
    iocInit may still sleep (see `ca_transport`): where each value will go is
    known, nothing serves yet. Call from a transport's `serve`, which starts
    after the CA and PVA ones'."""
    for future in (_ca_records_initialised, _pva_built):
        if future is not None:
            await asyncio.shield(future)


async def ca_initialised() -> None:
    """Once iocInit has returned (at once without a CA transport serving);
    call from a transport's `serve`, which starts after the CA one's."""
    if _ca_initialised is not None:
        await asyncio.shield(_ca_initialised)


def ca_still_initialising() -> bool:
    """Whether iocInit is still running (in EPICS's sleep, once `pvs_built`):
    work done on the loop now delays nothing."""
    return _ca_initialised is not None and not _ca_initialised.done()


# -- epicsdbbuilder ------------------------------------------------------------

_PASSED: Final = "_fastcs_ethercat_passed"
"""Attribute of a record type's validator: the (field, value)s that passed."""
_FIELD_ENTRIES: Final = "_fastcs_ethercat_field_entries"
"""Attribute of a record type's validator: field name -> a database entry
(cursor) kept on that field."""


@functools.cache
def install_field_memo() -> None:
    """Check each (field, value) of a record type once (idempotent).

    `dbVerify`'s verdict depends only on the field's definition and the
    value's text. The library walks its cursor over every field before the
    one it checks, a ctypes call each (a third of creating the records); a
    new value is verified instead on a cursor kept on its field, made once
    per (record type, field). A value that fails is checked again the
    library's way, so the error raised is the library's own.
    """
    from epicsdbbuilder import mydbstatic
    from epicsdbbuilder.dbd import DBEntry, ValidateDbField

    db: Any = mydbstatic  # its functions are bound at run time (ctypes)
    walk: Callable[[Any, str, Any], None] = ValidateDbField.ValidFieldValue

    def field_entry(self: Any, name: str) -> Any:
        """A cursor on field `name` of the validator's record type, or None."""
        entries: dict[str, Any] = self.__dict__.setdefault(_FIELD_ENTRIES, {})
        entry = entries.get(name)
        if entry is None:
            for field in self.dbEntry.iterate_fields():
                if field == name:
                    entry = entries[name] = DBEntry(self.dbEntry)  # a copy, kept
                    break
        return entry

    def valid_field_value(self: Any, name: str, value: Any) -> None:
        key = (name, str(value))
        known: set[tuple[str, str]] = self.__dict__.setdefault(_PASSED, set())
        if key in known:
            return
        self.ValidFieldName(name)
        entry = field_entry(self, name)
        if entry is None or db.dbVerify(entry, key[1]):
            walk(self, name, value)  # the library's own check raises its error
        known.add(key)

    ValidateDbField.ValidFieldValue = valid_field_value


_QUOTED: Final = re.compile(r'[\x00-\x1f"\\]')
"""The characters epicsdbbuilder's `quote_char` escapes."""


@functools.cache
def install_quick_db_text() -> None:
    """Write the .db file without a Python call per character or per line
    (idempotent); the text is the library's.

    epicsdbbuilder's `quote_string` maps `quote_char` over every character
    of every field of every record: 40 % of writing the database. A value
    with nothing to escape (almost all) is quoted as it is; any other goes
    through the library's own function. Its `Record.Print` then gives every
    line its own `print` (19 000 fields at 104 terminals): the lines of a
    record are joined and written at once. A record printed in its dbd's
    field order (not asked for here) still goes the library's way.
    """
    from epicsdbbuilder import recordbase

    library_quote: Callable[[str], str] = recordbase.quote_string

    def quote_string(value: str) -> str:
        if _QUOTED.search(value) is None:
            return '"' + value + '"'
        return library_quote(value)

    recordbase.quote_string = quote_string

    record: Any = recordbase.Record
    library_print = record.Print
    format_field = record._Record__FormatFieldForDb
    validate_field = record._Record__ValidateField

    def print_record(self: Any, output: Any, alphabetical: bool = True) -> None:
        if not alphabetical:
            library_print(self, output, alphabetical)
            return
        own = self.__dict__
        fields = own["_Record__fields"]
        lines = [
            "",
            *own["_Record__comments"],
            f'record({self._type!s}, "{self.name!s}")',
        ]
        lines.append("{")
        for name in sorted(fields):
            value = fields[name]
            if getattr(value, "ValidateLater", False):
                validate_field(self, name, value)
            padding = " " * (4 - len(name))
            lines.append(
                f"    field({name}, {padding}{format_field(self, name, value)})"
            )
        lines += [
            f'    alias("{alias!s}")' for alias in sorted(own["_Record__aliases"])
        ]
        lines += [
            f"    info({name!s}, {format_field(self, name, info)})"
            for name, info in own["_Record__infos"]
        ]
        lines.append("}\n")
        output.write("\n".join(lines))

    record.Print = print_record


# -- controllers ---------------------------------------------------------------


@functools.cache
def install_type_hint_memo() -> None:
    """Resolve each controller class's type hints once (idempotent).

    FastCS's `BaseController.__init__` calls `typing.get_type_hints` on the
    instance's class twice, which evaluates every string annotation each
    time: 822 calls for the 411 controllers of 104 terminals, ~35 ms of the
    start. The hints depend on the class only; each caller gets its own copy.
    """
    from fastcs.controllers import base_controller

    resolve: Callable[..., dict[str, Any]] | None = getattr(
        base_controller, "get_type_hints", None
    )
    if resolve is None:  # `shape_problems` says so
        return
    known: dict[type, dict[str, Any]] = {}

    def class_hints(obj: Any, *args: Any, **kwargs: Any) -> dict[str, Any]:
        if args or kwargs or not isinstance(obj, type):
            return resolve(obj, *args, **kwargs)
        hints = known.get(obj)
        if hints is None:
            hints = known[obj] = resolve(obj)
        return dict(hints)

    base_controller.get_type_hints = class_hints  # pyright: ignore[reportAttributeAccessIssue]


_PLAIN: Final = (str, bytes, int, float, bool, type(None))
_UNBOUND_MARKS: Final = ("__unbound_command__", "__unbound_scan__")


def _bindable(value: Any) -> bool:
    """Whether `_bind_attrs` could do anything with a class member: a plain
    method without FastCS's command or scan mark, or a constant, it skips."""
    if isinstance(value, staticmethod | classmethod):
        value = value.__func__
    if isinstance(value, types.FunctionType):
        return any(hasattr(value, mark) for mark in _UNBOUND_MARKS)
    return not isinstance(value, _PLAIN)


@functools.cache
def install_bind_memo() -> None:
    """Walk each controller class's members once (idempotent).

    FastCS's `BaseController._bind_attrs` walks the class's MRO for every
    instance and looks up every public member on it (a bound method made
    and checked four ways each): ~0.1 ms a controller, 411 controllers at
    104 terminals. What it can bind (attributes, commands, scans, anything
    not a plain method or constant) depends on the class only: `_walk_mro`
    gives just those names, found once per class.
    """
    from fastcs.controllers import base_controller

    controller: Any = base_controller.BaseController
    walk: Any = controller.__dict__.get("_walk_mro")
    if not isinstance(walk, classmethod):  # `shape_problems` says so
        return
    names_of = walk.__func__
    known: dict[type, list[str]] = {}

    def bindable_names(cls: type) -> list[str]:
        found = known.get(cls)
        if found is None:
            found = known[cls] = [
                name
                for name in names_of(cls)
                if _bindable(inspect.getattr_static(cls, name, None))
            ]
        return list(found)

    controller._walk_mro = classmethod(bindable_names)


# -- imports -------------------------------------------------------------------

UNUSED_TRANSPORTS: Final = frozenset(
    {"fastcs.transports.rest", "fastcs.transports.graphql", "fastcs.transports.tango"}
)
IOC_MODULES: Final = (
    "fastcs",
    "fastcs.transports.epics.ca.transport",
    "fastcs.transports.epics.pva.transport",
)
"""What an IOC imports anyway: FastCS, softioc (CA) and p4p (PVA)."""


class _RefuseUnused(importlib.abc.MetaPathFinder):
    """Makes the unused transports look not installed (FastCS skips them)."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: types.ModuleType | None = None,
    ) -> ModuleSpec | None:
        if fullname in UNUSED_TRANSPORTS:
            raise ModuleNotFoundError(f"{fullname} left out", name=fullname)
        return None


def _caller_package() -> str:
    """What setuptools_dso's `_auto_pkg` returns: the module name of the frame
    that called `find_dso`/`dylink_prepare_dso` (two frames up)."""
    return sys._getframe(2).f_globals["__name__"]  # pyright: ignore[reportPrivateUsage]


_DEFERRED: Final = {
    "IPython.terminal.embed": ("InteractiveShellEmbed",),
    "fastcs.launch": ("launch",),
    "fastcs.transports.epics.emission": ("emit_docs_files", "emit_gui_files"),
    "fastcs.transports.epics.gui": ("EpicsGUI",),
    "fastcs.transports.epics.pva.gui": ("PvaEpicsGUI",),
    "prompt_toolkit.patch_stdout": ("StdoutProxy",),
}
"""Modules FastCS imports at start only to define names an IOC without an
interactive shell or GUI files never calls (IPython, pvi; prompt_toolkit,
0.1 s, for `fastcs.logging.configure_logging`, which this IOC does not call:
`logs.py` routes FastCS's log; ruamel.yaml, 30 modules, for FastCS's own
YAML launcher, where `launch.py` builds the transports itself): stood in for
by names that import the real module when first called."""
_DSO_PACKAGE: Final = "setuptools_dso"
_DSO_RUNTIME: Final = "setuptools_dso.runtime"
_DSO_NAMES: Final = ("find_dso", "dylink_prepare_dso")
"""The package EPICS's wheels find their libraries with: its `__init__`
imports setuptools (and with it pkg_resources, which reads the metadata of
every installed distribution) to offer build commands; at run time only
these names of its `runtime` are used."""


def _deferred(module: str, name: str) -> Callable[..., Any]:
    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(importlib.import_module(module), name)(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    return call


def _stand_ins() -> dict[str, types.ModuleType]:
    """Stand-in modules for what is not imported yet (see `_DEFERRED`)."""
    found: dict[str, types.ModuleType] = {}
    for name, names in _DEFERRED.items():
        if name not in sys.modules and importlib.util.find_spec(name.split(".")[0]):
            module = found[name] = types.ModuleType(name, "stands in at start")
            for attribute in names:
                module.__dict__[attribute] = _deferred(name, attribute)
    if _DSO_PACKAGE not in sys.modules:
        spec = importlib.util.find_spec(_DSO_PACKAGE)
        if spec is not None and spec.submodule_search_locations:
            package = found[_DSO_PACKAGE] = types.ModuleType(_DSO_PACKAGE)
            package.__path__ = list(spec.submodule_search_locations)
    return found


@contextmanager
def lean_imports() -> Iterator[None]:
    """Within: unused FastCS transports are not imported, DSOs found quickly
    and without setuptools, `_DEFERRED` modules stood in for."""
    stood_in = _stand_ins()
    sys.modules.update(stood_in)
    finder = _RefuseUnused()
    sys.meta_path.insert(0, finder)
    try:
        runtime: Any = importlib.import_module(_DSO_RUNTIME)
    except ImportError:
        runtime = None
    package = stood_in.get(_DSO_PACKAGE)
    if package is not None and runtime is not None:
        for name in _DSO_NAMES:
            package.__dict__[name] = getattr(runtime, name)
    auto_pkg = getattr(runtime, "_auto_pkg", None)
    if runtime is not None and auto_pkg is not None:
        runtime._auto_pkg = _caller_package
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        if runtime is not None and auto_pkg is not None:
            runtime._auto_pkg = auto_pkg
        for name, module in stood_in.items():
            if sys.modules.get(name) is module:
                del sys.modules[name]


def import_ioc_modules() -> None:
    """Import FastCS with its CA and PVA transports the quick way (once),
    EPICS without real-time threads (`scheduling`); the PVA read PVs FastCS
    makes are posted to lazily (`_ReadPv`), controller classes' type hints
    resolved once (`install_type_hint_memo`)."""
    if not all(name in sys.modules for name in IOC_MODULES):
        from fastcs_ethercat.ioc.scheduling import give_up_realtime_scheduling

        give_up_realtime_scheduling()  # before EPICS starts a thread
        with lean_imports():
            for name in IOC_MODULES:
                importlib.import_module(name)
    _make_read_pvs_lazy()
    install_p4p_type_memo()
    install_type_hint_memo()
    install_bind_memo()


# -- the check at start --------------------------------------------------------


def _version(text: str) -> tuple[int, ...]:
    numbers: list[int] = []
    for part in text.split("."):
        digits = "".join(c for c in part if c.isdigit()) if part[:1].isdigit() else ""
        if not digits:
            break
        numbers.append(int(digits))
    return tuple(numbers)


def _range(package: str) -> str:
    low, high = TESTED[package]
    return f">={'.'.join(map(str, low))},<{'.'.join(map(str, high))}"


def version_problems() -> list[str]:
    """Installed versions outside the tested ranges, one text each."""
    problems: list[str] = []
    for package, (low, high) in TESTED.items():
        try:
            installed = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            problems.append(f"{package} is not installed (tested {_range(package)})")
            continue
        if not low <= _version(installed) < high:
            problems.append(
                f"{package} {installed} is installed, fastcs-ethercat is tested "
                f"with {package}{_range(package)}"
            )
    return problems


def shape_problems() -> list[str]:
    """Internals used above that the installed packages no longer have."""
    problems: list[str] = []
    for closure in (CA_READ, CA_WRITE, PVA_READ, PVA_WRITE):
        outer = getattr(importlib.import_module(closure.module), closure.outer, None)
        if not isinstance(outer, types.FunctionType):
            problems.append(f"fastcs: {closure.module}.{closure.outer} is gone")
            continue
        inner = [
            const
            for const in outer.__code__.co_consts
            if isinstance(const, types.CodeType) and const.co_name == closure.inner
        ]
        if not inner:
            problems.append(f"fastcs: {closure.qualname} is gone")
        elif closure.cell not in inner[0].co_freevars:
            problems.append(f"fastcs: {closure.qualname} has no {closure.cell}")
    parse = getattr(importlib.import_module(_PVA_IOC_MODULE), "parse_attributes", None)
    names = parse.__code__.co_names if isinstance(parse, types.FunctionType) else ()
    if "make_shared_read_pv" not in names:
        problems.append(f"fastcs: {_PVA_IOC_MODULE} makes its read PVs another way")
    for module in (_PVA_TYPES_MODULE, _PVA_MODULE):
        if "make_p4p_type" not in vars(importlib.import_module(module)):
            problems.append(f"fastcs: {module} no longer has make_p4p_type")
    pva_ioc: Any = getattr(importlib.import_module(_PVA_IOC_MODULE), "P4PIOC", None)
    run = getattr(pva_ioc, "run", None)
    if not isinstance(run, types.FunctionType) or (
        "_build_providers" not in run.__code__.co_names
    ):
        problems.append("fastcs: P4PIOC.run no longer builds by _build_providers")
    from fastcs.attributes import AttrR, AttrRW, AttrW
    from fastcs.datatypes import Int

    fields: dict[type[Any], tuple[str, ...]] = {
        AttrR: ("_on_update_callbacks", "_on_update_events", "_value"),
        AttrW: ("_sync_setpoint_callbacks", "_call_sync_setpoint_callbacks"),
        AttrRW: ("_setpoint_initialised",),
    }
    for kind, names in fields.items():
        sample = kind(Int())
        problems += [
            f"fastcs: {kind.__name__}.{name} is gone"
            for name in names
            if not hasattr(sample, name)
        ]
    from fastcs.transports.epics.ca.ioc import EpicsCAIOC
    from fastcs.transports.epics.ca.transport import EpicsCATransport

    if "_ioc" not in EpicsCATransport.serve.__code__.co_names or not callable(
        getattr(EpicsCAIOC, "run", None)
    ):
        problems.append("fastcs: EpicsCATransport.serve no longer runs _ioc.run")
    from fastcs.controllers import base_controller

    controller = base_controller.BaseController
    if not isinstance(controller.__dict__.get("_walk_mro"), classmethod):
        problems.append("fastcs: BaseController._walk_mro is no longer a classmethod")
    if "_walk_mro" not in controller._bind_attrs.__code__.co_names:  # pyright: ignore[reportPrivateUsage]
        problems.append("fastcs: BaseController._bind_attrs no longer calls _walk_mro")
    for method in (controller._find_type_hints, controller._bind_attrs):  # pyright: ignore[reportPrivateUsage]
        if "get_type_hints" not in method.__code__.co_names:
            problems.append(
                f"fastcs: BaseController.{method.__name__} no longer calls "
                "get_type_hints"
            )
    return problems + _softioc_problems() + _epicsdbbuilder_problems()


def _softioc_problems() -> list[str]:
    from softioc import device_core, imports
    from softioc.device import ProcessDeviceSupportIn, ProcessDeviceSupportOut

    problems: list[str] = []
    if not callable(getattr(device_core, "LookupRecord", None)):
        problems.append("softioc: device_core.LookupRecord is gone")
    core = device_core.DeviceSupportCore
    if "_DeviceSupportCore__ioscanpvt" not in core.trigger.__code__.co_names:
        problems.append("softioc: trigger() no longer uses __ioscanpvt")
    if "scanIoInit" not in core._get_ioinit_info.__code__.co_names:  # pyright: ignore[reportPrivateUsage]
        problems.append("softioc: get_ioint_info no longer calls scanIoInit")
    if "_value" not in ProcessDeviceSupportIn._process.__code__.co_names:
        problems.append("softioc: in records no longer process _value")
    if not hasattr(ProcessDeviceSupportIn, "_value_to_epics"):
        problems.append("softioc: in records have no _value_to_epics")
    if _ON_UPDATE not in ProcessDeviceSupportOut._process.__code__.co_names:
        problems.append("softioc: out records no longer call __on_update")
    for name in ("recGblResetAlarms", "callbackSetQueueSize"):
        if not hasattr(imports, name):
            problems.append(f"softioc: imports.{name} is gone")
    return problems


def _epicsdbbuilder_problems() -> list[str]:
    from epicsdbbuilder import dbd
    from epicsdbbuilder.dbd import ValidateDbField

    problems: list[str] = []
    if not callable(getattr(ValidateDbField, "ValidFieldValue", None)):
        problems.append("epicsdbbuilder: ValidateDbField.ValidFieldValue is gone")
    if not callable(getattr(dbd, "DBEntry", None)):
        problems.append("epicsdbbuilder: dbd.DBEntry is gone")
    from epicsdbbuilder import recordbase

    if not callable(getattr(recordbase.Record, "_FieldValue", None)):
        problems.append("epicsdbbuilder: Record._FieldValue is gone")
    if not callable(getattr(recordbase.Record, "_Record__ValidateField", None)):
        problems.append("epicsdbbuilder: Record.__ValidateField is gone")
    kept = recordbase.Record.__init__.__code__.co_consts
    for part in ("__fields", "__aliases", "__comments", "__infos"):
        if part not in kept:
            problems.append(f"epicsdbbuilder: records no longer keep {part}")
    formats = getattr(recordbase.Record, "_Record__FormatFieldForDb", None)
    if not callable(getattr(recordbase, "quote_string", None)) or not (
        isinstance(formats, types.FunctionType)
        and "quote_string" in formats.__code__.co_names
    ):
        problems.append("epicsdbbuilder: records are no longer quoted by quote_string")
    return problems


def check_installed() -> None:
    """Stop (`UserError`, one line) unless FastCS, softioc and epicsdbbuilder
    are versions this was tested with and have the internals it uses."""
    problems = version_problems()
    if not problems:
        import_ioc_modules()
        problems = shape_problems()
    if problems:
        raise UserError(
            "; ".join(problems) + ": install the versions pyproject.toml names",
            where="packages",
        )
