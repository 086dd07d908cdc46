"""What FastCS 0.14 and softioc 4.7 do not offer yet, through their
private names: the one module of the IOC that touches them. Each item says
why, and what upstream change retires it.

- **Updates with a timestamp and an alarm.** `AttrR.update(value)` has no
  time and no alarm: each transport stamps the value with the time its
  callback runs. A poll cycle's values were all read by one ADS request and
  carry that request's time and their channel's alarm. `ValueRoute.post`
  sets what `update()` sets (`AttrR._value`, `_on_update_events`, an
  `AttrRW`'s first setpoint sync through `_setpoint_initialised` and
  `_call_sync_setpoint_callbacks`) and hands the value to the in record
  through softioc's public `set(value, severity, alarm, timestamp)`, so EPICS
  record support processes it (alarm limits, deadbands, links) and CA and
  PVA (QSRV) serve the result. The CA transport's own on-update callback
  (recognised in `_on_update_callbacks` by its module and name) is left
  out; any other is called. Retired by FastCS's `Update` (on its main
  branch): then `attribute.update(Update(...))`.
- **CA out-record alarms.** softioc stages an out record's alarm only for
  its next processing, and processing an out record writes to the PLC:
  `_set_out_record_alarm` does what processing would (NSEV/NSTA through
  softioc's `_record` view, EPICS's `recGblResetAlarms` and
  `db_post_events`). Retired by an alarm setter on softioc's out records.
- **Setpoints after a put.** FastCS's CA put handler stages MAJOR on a failed
  put and NO_ALARM on a good one; `watch_ca_puts` runs the IOC's own verdict
  after it, before the put completes (`_ProcessDeviceSupportOut__on_update`,
  softioc's on-update slot), so `caput -c` sees the IOC's alarm.
  `sync_setpoint` shows a value on every setpoint PV (FastCS's
  `_call_sync_setpoint_callbacks`). Retired by a FastCS put verdict hook.

`check_installed()` runs at every IOC start: each package's version must be
one this was tested with and every private name used here must exist, else
the IOC stops with one line naming the package and version.
"""

from __future__ import annotations

import ctypes
import enum
import functools
import importlib
import importlib.metadata
import math
import sys
import time
import types
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final, NamedTuple

from fastcs_ethercat.errors import UserError

if TYPE_CHECKING:
    from fastcs.attributes import Attribute, AttrR

TESTED: Final = {
    "fastcs": ((0, 14, 4), (0, 15)),
    "softioc": ((4, 7), (4, 8)),
}
"""Package -> (lowest tested version, first version not tested), as in
pyproject.toml: the two whose private names this module uses."""


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


# -- where an attribute is served --------------------------------------------


@dataclass(frozen=True)
class _Callback:
    """One of FastCS's CA transport callbacks, recognised by its name."""

    module: str
    outer: str
    inner: str

    @property
    def qualname(self) -> str:
        return f"{self.outer}.<locals>.{self.inner}"

    def made(self, callback: Callable[..., Any]) -> bool:
        """Whether FastCS made `callback` here."""
        return (
            getattr(callback, "__module__", None) == self.module
            and getattr(callback, "__qualname__", None) == self.qualname
        )


_CA_MODULE: Final = "fastcs.transports.epics.ca.ioc"
CA_READ: Final = _Callback(_CA_MODULE, "_create_and_link_read_pv", "async_record_set")
"""The CA transport's on-update callback: `ValueRoute` sets the record
itself (with time and alarm), so this one is not called."""
RBV_SUFFIX: Final = "_RBV"
_ON_UPDATE: Final = "_ProcessDeviceSupportOut__on_update"
"""Where a softioc out record keeps its on-update callback."""
_WATCHED: Final = "_fastcs_ethercat_watched"
"""Set on an out record whose puts `watch_ca_puts` follows."""


class Parts(enum.IntFlag):
    """Which records of an attribute an alarm goes to."""

    READBACK = enum.auto()
    """What the PLC holds: the in record (`_RBV` of an output)."""
    SETPOINT = enum.auto()
    """What was asked for: an output's out record."""
    ALL = READBACK | SETPOINT


def ca_name(attribute: Attribute[Any, Any]) -> str:
    """The PV FastCS makes for `attribute` (an `AttrRW`'s setpoint)."""
    from fastcs.transports.epics.util import pv_prefix_from_path
    from fastcs.util import snake_to_pascal

    return f"{pv_prefix_from_path(attribute.path)}:{snake_to_pascal(attribute.name)}"


def _ca_names(attribute: Attribute[Any, Any], *, reads: bool) -> list[str]:
    """Records of `attribute`: the out record, and the in record if `reads`."""
    from fastcs.attributes import AttrR, AttrW

    name = ca_name(attribute) if attribute.path else ""
    if not name:
        return []
    found = [name] if isinstance(attribute, AttrW) else []
    if reads and isinstance(attribute, AttrR):
        found.append(name + RBV_SUFFIX if isinstance(attribute, AttrW) else name)
    return found


def database_records(attribute: Attribute[Any, Any], *, reads: bool) -> list[Any]:
    """The database records (epicsdbbuilder) of `attribute`'s out record, and
    in record if `reads`, to set fields on between the transport's connect
    and iocInit."""
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
    if "softioc.device_core" not in sys.modules:  # no database yet
        return None
    from softioc.device_core import LookupRecord

    try:
        return LookupRecord(name)
    except KeyError:
        return None


@dataclass(frozen=True)
class Endpoints:
    """The records serving one attribute (None: not made), on CA and PVA.

    `ca_in`/`ca_out` are softioc device supports; `others` every on-update
    callback but the CA transport's own (anyone's), which gets each value
    as from `update()`.
    """

    attribute: Attribute[Any, Any]
    ca_in: Any = None
    ca_out: Any = None
    others: tuple[Callable[[Any], Any], ...] = ()

    def __bool__(self) -> bool:
        return self.ca_in is not None or self.ca_out is not None

    def publish_alarm(
        self, severity: int, status: int, parts: Parts = Parts.ALL
    ) -> int:
        """Give the records of `parts` this alarm, value unchanged; how many
        were reached."""
        reached = 0
        if self.ca_in is not None and Parts.READBACK in parts:
            # the time too: the record is on device time
            self.ca_in.set_alarm(severity, status, timestamp=time.time())
            reached += 1
        if self.ca_out is not None and Parts.SETPOINT in parts:
            _set_out_record_alarm(self.ca_out, severity, status)
            reached += 1
        return reached


def endpoints_of(attribute: Attribute[Any, Any]) -> Endpoints:
    """Where `attribute` is served (once the transport has connected)."""
    from fastcs.attributes import AttrR, AttrW

    read_callbacks: list[Callable[..., Any]] = []
    if isinstance(attribute, AttrR):
        read_callbacks = [cb for cb, _ in attribute._on_update_callbacks or ()]  # pyright: ignore[reportPrivateUsage]
    names = _ca_names(attribute, reads=True)
    ca_out = _ca_record(names[0]) if names and isinstance(attribute, AttrW) else None
    ca_in = _ca_record(names[-1]) if names and isinstance(attribute, AttrR) else None
    others = tuple(cb for cb in read_callbacks if not CA_READ.made(cb))
    return Endpoints(attribute, ca_in=ca_in, ca_out=ca_out, others=others)


# -- publishing values ---------------------------------------------------------

_INVALID: Final = 3
_UDF: Final = 17


class ValueRoute:
    """Publishes `Update`s of one attribute, once the database serves.

    `post` hands the value to the in record (softioc's `set`: EPICS processes
    the record, its alarm limits and deadbands apply, CA and PVA monitors
    get it) and returns what must still be awaited: the first setpoint sync
    of an `AttrRW`, and on-update callbacks of anyone else, as `update()`
    would call them; None almost always.
    """

    def __init__(self, attribute: AttrR[Any, Any]) -> None:
        from fastcs.attributes import AttrRW
        from fastcs.datatypes import Float
        from fastcs.transports.epics.ca.util import cast_to_epics_type

        self.attribute = attribute
        self.endpoints = endpoints_of(attribute)
        self._writable = isinstance(attribute, AttrRW)
        self._to_epics = cast_to_epics_type
        self._is_float = isinstance(attribute.datatype, Float)
        device = self.endpoints.ca_in
        self._set: Callable[..., None] | None = (
            device.set if device is not None else None
        )

    def post(self, update: Update) -> Awaitable[None] | None:
        """What `attribute.update(update)` will do: value, record, setpoint."""
        attribute, value = self.attribute, update.value
        attribute._value = value  # pyright: ignore[reportPrivateUsage]
        events = attribute._on_update_events  # pyright: ignore[reportPrivateUsage]
        if events:
            attribute._on_update_events = {e for e in events if not e.set(value)}  # pyright: ignore[reportPrivateUsage]
        if self._set is not None:
            severity, status = update.severity, update.status
            if self._is_float and math.isnan(value):  # as an ai record reads NaN
                severity, status = _INVALID, _UDF
            self._set(
                self._to_epics(attribute.datatype, value),
                severity,
                status,
                update.timestamp,
            )
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
        """`post` one update and await what it leaves."""
        pending = self.post(update)
        if pending is not None:
            await pending


# -- softioc -------------------------------------------------------------------


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
    for name in ("dbScanLock", "dbScanUnlock"):
        getattr(dbCore, name).argtypes = pointer
        getattr(dbCore, name).restype = None
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
    """Show `value` on the setpoint of `attribute` (its out record, without
    processing), as FastCS does at start."""
    from fastcs.attributes import AttrW

    if isinstance(attribute, AttrW):
        await attribute._call_sync_setpoint_callbacks(value)  # pyright: ignore[reportPrivateUsage]


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
    """Private names used above that the installed packages no longer have."""
    problems: list[str] = []
    outer = getattr(importlib.import_module(CA_READ.module), CA_READ.outer, None)
    if not isinstance(outer, types.FunctionType) or not any(
        isinstance(const, types.CodeType) and const.co_name == CA_READ.inner
        for const in outer.__code__.co_consts
    ):
        problems.append(f"fastcs: {CA_READ.module}.{CA_READ.qualname} is gone")
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
    return problems + _softioc_problems()


def _softioc_problems() -> list[str]:
    from softioc import device_core, imports
    from softioc.device import ProcessDeviceSupportOut

    problems: list[str] = []
    if not callable(getattr(device_core, "LookupRecord", None)):
        problems.append("softioc: device_core.LookupRecord is gone")
    if _ON_UPDATE not in ProcessDeviceSupportOut._process.__code__.co_names:
        problems.append("softioc: out records no longer call __on_update")
    if "_record" not in device_core.DeviceSupportCore._init_record.__code__.co_names:  # pyright: ignore[reportPrivateUsage]
        problems.append("softioc: records no longer keep their fields in _record")
    if not hasattr(imports, "callbackSetQueueSize"):
        problems.append("softioc: imports.callbackSetQueueSize is gone")
    return problems


def import_ioc_modules() -> None:
    """Import FastCS with its CA transport (once), EPICS without
    real-time threads (`scheduling`)."""
    if not all(name in sys.modules for name in IOC_MODULES):
        from fastcs_ethercat.ioc.scheduling import give_up_realtime_scheduling

        give_up_realtime_scheduling()  # before EPICS starts a thread
        for name in IOC_MODULES:
            importlib.import_module(name)


IOC_MODULES: Final = (
    "fastcs",
    "fastcs.transports.epics.ca.transport",
)
"""What an IOC imports: FastCS and softioc."""


def check_installed() -> None:
    """Stop (`UserError`, one line) unless FastCS and softioc are versions
    this was tested with and have the private names it uses."""
    problems = version_problems()
    if not problems:
        import_ioc_modules()
        problems = shape_problems()
    if problems:
        raise UserError(
            "; ".join(problems) + ": install the versions pyproject.toml names",
            where="packages",
        )
