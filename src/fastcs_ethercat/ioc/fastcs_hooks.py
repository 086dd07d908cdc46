"""Find the softioc record and the p4p PV that FastCS made for an attribute.

Written against FastCS 0.14.4 (with softioc 4.7 and p4p 4.3). That FastCS has
no API for an attribute's alarm state and keeps what its EPICS transports
build for an attribute only inside the callbacks they register on it:

- CA (`fastcs.transports.epics.ca.ioc`): the in record (`<Name>` of an AttrR,
  `<Name>_RBV` of an AttrRW) is the closure cell `record` of
  `_create_and_link_read_pv.<locals>.async_record_set`, an on-update callback;
  the out record (`<Name>` of an AttrW or AttrRW) is the cell `record` of
  `_create_and_link_write_pv.<locals>.set_setpoint_without_process`, a
  sync-setpoint callback.
- PVA (`fastcs.transports.epics.pva._pv_handlers`): the read SharedPV is the
  cell `shared_pv` of `make_shared_read_pv.<locals>.set_readback` (on-update),
  the write SharedPV that of `make_shared_write_pv.<locals>.set_setpoint`
  (sync-setpoint).

The callbacks exist once the transport has connected (CA: in `connect()`,
before iocInit) or started serving (PVA: the first step of `serve()`), so
look them up when needed rather than once at build time.

softioc 4.7 can set an out record's alarm only for its next processing
(`set(process=False)` stages NSEV/NSTA), and processing an out record of
FastCS writes to the device; `set_out_record_alarm` therefore does what
processing would through EPICS's own database calls, using softioc's record
field view (`device._record`, a `softioc.fields._Record`).

Publishing a polled value (`store_value`, `init_setpoint`, `read_route`)
sets what `AttrR.update()` would set (`_value`, the `_on_update_events`,
an `AttrRW`'s first setpoint sync) and leaves the posting to the caller, who
gives every record and PV the poll cycle's one timestamp: `update()` lets
each transport stamp its own time. CA in records on that path get TSE=-2
(`use_device_time`), so EPICS keeps the time the device support set.

softioc's `set()` queues an in record's processing with `scanIoRequest`
through ctypes, which releases the GIL for the call: the EPICS callback
thread that processes the record wakes, takes the GIL to run softioc's
Python device support, and the caller waits for it back, for every record.
`in_record_setter` stores the value as `set()` does and queues the same
request without letting go of the GIL (a PyDLL binding; scanIoRequest only
appends to a queue and never waits), so the callback threads process a whole
poll cycle's records in one turn: a third of the CPU per published value.

This module is the only place in the project that knows these internals.
Nothing is patched. `check_fastcs_shape()` (run by the tests) fails loudly
when a FastCS upgrade moves any of the FastCS parts; the softioc part is
checked end to end by tests/test_ioc_alarms.py (a monitor on an out record).
"""

from __future__ import annotations

import ctypes
import functools
import time
import types
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Final

from fastcs.attributes import Attribute, AttrR, AttrRW, AttrW

WRITTEN_AGAINST_FASTCS: Final = "0.14.4"

_CA_MODULE: Final = "fastcs.transports.epics.ca.ioc"
_PVA_MODULE: Final = "fastcs.transports.epics.pva._pv_handlers"


@dataclass(frozen=True)
class _Closure:
    """One FastCS callback whose closure holds a record or a PV."""

    module: str
    outer: str
    inner: str
    cell: str

    @property
    def qualname(self) -> str:
        return f"{self.outer}.<locals>.{self.inner}"


CA_READ: Final = _Closure(
    _CA_MODULE, "_create_and_link_read_pv", "async_record_set", "record"
)
CA_WRITE: Final = _Closure(
    _CA_MODULE, "_create_and_link_write_pv", "set_setpoint_without_process", "record"
)
PVA_READ: Final = _Closure(
    _PVA_MODULE, "make_shared_read_pv", "set_readback", "shared_pv"
)
PVA_WRITE: Final = _Closure(
    _PVA_MODULE, "make_shared_write_pv", "set_setpoint", "shared_pv"
)
_ALL: Final = (CA_READ, CA_WRITE, PVA_READ, PVA_WRITE)


@dataclass(frozen=True)
class Endpoints:
    """What serves one attribute: None where a transport made nothing (yet).

    `ca_in`/`ca_out` are softioc `RecordWrapper`s, `pva_read`/`pva_write`
    p4p asyncio `SharedPV`s.
    """

    ca_in: Any = None
    ca_out: Any = None
    pva_read: Any = None
    pva_write: Any = None

    def __bool__(self) -> bool:
        return any(
            x is not None
            for x in (self.ca_in, self.ca_out, self.pva_read, self.pva_write)
        )


def endpoints_of(attribute: Attribute[Any, Any]) -> Endpoints:
    """The CA records and PVA PVs FastCS serves `attribute` with, so far."""
    read_callbacks: Iterable[Callable[..., Any]] = ()
    write_callbacks: Iterable[Callable[..., Any]] = ()
    if isinstance(attribute, AttrR):
        read_callbacks = [cb for cb, _ in attribute._on_update_callbacks or ()]  # pyright: ignore[reportPrivateUsage]
    if isinstance(attribute, AttrW):
        write_callbacks = attribute._sync_setpoint_callbacks  # pyright: ignore[reportPrivateUsage]
    return Endpoints(
        ca_in=_find(read_callbacks, CA_READ),
        ca_out=_find(write_callbacks, CA_WRITE),
        pva_read=_find(read_callbacks, PVA_READ),
        pva_write=_find(write_callbacks, PVA_WRITE),
    )


def _find(callbacks: Iterable[Callable[..., Any]], closure: _Closure) -> Any:
    for callback in callbacks:
        if _is(callback, closure):
            return _cell(callback, closure.cell)
    return None


def _is(callback: Callable[..., Any], closure: _Closure) -> bool:
    return (
        getattr(callback, "__module__", None) == closure.module
        and getattr(callback, "__qualname__", None) == closure.qualname
    )


def _cell(function: Callable[..., Any], name: str) -> Any:
    code: types.CodeType = function.__code__  # type: ignore[attr-defined]
    cells = function.__closure__ or ()  # type: ignore[attr-defined]
    return cells[code.co_freevars.index(name)].cell_contents


class FastCSShapeError(RuntimeError):
    """The installed FastCS no longer has the shape this module reads."""


def check_fastcs_shape() -> None:
    """Raise `FastCSShapeError` unless every closure and list read above exists.

    Static: checks FastCS's code objects and attribute fields, not a live IOC.
    """
    import importlib

    problems: list[str] = []
    for closure in _ALL:
        module = importlib.import_module(closure.module)
        outer = getattr(module, closure.outer, None)
        if not isinstance(outer, types.FunctionType):
            problems.append(f"{closure.module}.{closure.outer} is gone")
            continue
        inner = [
            const
            for const in outer.__code__.co_consts
            if isinstance(const, types.CodeType) and const.co_name == closure.inner
        ]
        if not inner:
            problems.append(f"{closure.module}.{closure.qualname} is gone")
        elif closure.cell not in inner[0].co_freevars:
            problems.append(f"{closure.qualname} no longer closes over {closure.cell}")
    from fastcs.datatypes import Int

    fields = {
        AttrR: ("_on_update_callbacks", "_on_update_events", "_value"),
        AttrW: ("_sync_setpoint_callbacks", "_call_sync_setpoint_callbacks"),
        AttrRW: ("_setpoint_initialised",),
    }
    for kind, names in fields.items():
        sample = kind(Int())
        problems += [
            f"{kind.__name__}.{name} is gone"
            for name in names
            if not hasattr(sample, name)
        ]
    problems += _softioc_problems()
    if problems:
        raise FastCSShapeError(
            f"FastCS changed shape (module written against {WRITTEN_AGAINST_FASTCS}): "
            + "; ".join(problems)
        )


def set_out_record_alarm(record: Any, severity: int, status: int) -> None:
    """Give a softioc out record this alarm now, value and device untouched.

    Stage the alarm as softioc does (kept for the record's next processing),
    then, under the record's lock, do what processing would: stage it in
    NSEV/NSTA, let EPICS move it to SEVR/STAT (recGblResetAlarms, which posts
    those fields) and post VAL with DBE_ALARM, so monitors see it. Before
    iocInit there is no record yet; softioc applies the staged alarm at init.
    """
    record.set(record.get(), process=False, severity=severity, alarm=status)
    fields = getattr(record, "_record", None)  # softioc's view of its fields
    if fields is None:
        return
    functions = _database_functions()
    base: int = fields.record.value
    value_address = ctypes.c_void_p(base + fields.fields["VAL"][0])
    functions.lock(fields)
    try:
        fields.NSEV = severity
        fields.NSTA = status
        fields.TIME = time.time()
        changed = functions.reset_alarms(fields)
        if changed:
            functions.post_events(ctypes.c_void_p(base), value_address, changed)
    finally:
        functions.unlock(fields)


@dataclass(frozen=True)
class _DatabaseFunctions:
    lock: Any
    unlock: Any
    reset_alarms: Any
    post_events: Any


@functools.cache
def _database_functions() -> _DatabaseFunctions:
    """EPICS database calls, loaded only once a CA IOC (softioc) runs."""
    from epicscorelibs.ioc import dbCore
    from softioc.imports import recGblResetAlarms

    for name in ("dbScanLock", "dbScanUnlock"):
        getattr(dbCore, name).argtypes = (ctypes.c_void_p,)
        getattr(dbCore, name).restype = None
    post_events = dbCore.db_post_events
    post_events.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint)
    post_events.restype = ctypes.c_int
    return _DatabaseFunctions(
        dbCore.dbScanLock, dbCore.dbScanUnlock, recGblResetAlarms, post_events
    )


@dataclass(frozen=True)
class ReadRoute:
    """Where a new value of one attribute goes: its CA in record and PVA read
    PV (None where a transport made none), and every other on-update callback
    (another transport's, or anyone's), which gets the value as from update()."""

    ca_in: Any
    pva_read: Any
    others: tuple[Callable[[Any], Any], ...]


def read_route(attribute: AttrR[Any, Any]) -> ReadRoute:
    """The route of `attribute`'s values, once the transports serve."""
    callbacks = [cb for cb, _ in attribute._on_update_callbacks or ()]  # pyright: ignore[reportPrivateUsage]
    others = tuple(
        cb for cb in callbacks if not (_is(cb, CA_READ) or _is(cb, PVA_READ))
    )
    return ReadRoute(_find(callbacks, CA_READ), _find(callbacks, PVA_READ), others)


def use_device_time(record: Any) -> None:
    """Let `record` keep the TIME its device support sets (TSE=-2), so a
    `set(..., timestamp=t)` shows t rather than the time of processing."""
    fields = getattr(record, "_record", None)
    if fields is not None:  # after iocInit: the live record
        fields.TSE = -2
    else:  # before: the database still being built
        record.TSE = -2


def store_value(attribute: AttrR[Any, Any], value: Any) -> None:
    """Make `value` the attribute's value, as `update()` does, posting nothing."""
    attribute._value = value  # pyright: ignore[reportPrivateUsage]
    events = attribute._on_update_events  # pyright: ignore[reportPrivateUsage]
    if events:
        attribute._on_update_events = {e for e in events if not e.set(value)}  # pyright: ignore[reportPrivateUsage]


async def init_setpoint(attribute: AttrR[Any, Any], value: Any) -> None:
    """An `AttrRW`'s first value also becomes its setpoint, as in `update()`."""
    if isinstance(attribute, AttrRW) and not attribute._setpoint_initialised:  # pyright: ignore[reportPrivateUsage]
        await attribute._call_sync_setpoint_callbacks(value)  # pyright: ignore[reportPrivateUsage]
        attribute._setpoint_initialised = True  # pyright: ignore[reportPrivateUsage]


def in_record_setter(record: Any) -> Callable[[Any, float], None]:
    """`set(value, timestamp=stamp)` of a softioc in record, NO_ALARM, that
    queues the record's processing without releasing the GIL (see above)."""
    device = record._RecordWrapper__device
    to_epics = device._value_to_epics
    request = _scan_io_request_keeping_gil()

    def set_value(value: Any, stamp: float) -> None:
        device._value = (to_epics(value), 0, 0, stamp)
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


def _softioc_problems() -> list[str]:
    """What `in_record_setter` needs of softioc and is not there."""
    from softioc.device import ProcessDeviceSupportIn
    from softioc.device_core import DeviceSupportCore
    from softioc.pythonSoftIoc import RecordWrapper

    problems: list[str] = []
    if (
        "_DeviceSupportCore__ioscanpvt"
        not in DeviceSupportCore.trigger.__code__.co_names
    ):
        problems.append("softioc's trigger() no longer uses __ioscanpvt")
    if "_value" not in ProcessDeviceSupportIn._process.__code__.co_names:
        problems.append("softioc's in records no longer process _value")
    if not hasattr(ProcessDeviceSupportIn, "_value_to_epics"):
        problems.append("softioc's in records have no _value_to_epics")
    if "_RecordWrapper__device" not in RecordWrapper.__getattr__.__code__.co_names:
        problems.append("softioc's RecordWrapper no longer keeps __device")
    return problems
