"""Where a FastCS attribute is served, the value it holds, and the private
names of FastCS and softioc the IOC needs (each with why and what retires it).

FastCS's CA transport makes the records of every attribute (`ioc.database`
turns its input records into ordinary EPICS records whose value the IOC
puts). This module finds them by the name FastCS gives them and posts to
them through EPICS's database access (`ioc.dbaccess`): a value into an
input record, which EPICS processes; an alarm onto an input record (raised,
then the record processed) or an output record (made current without
processing, which would write to the PLC); a setpoint's value onto an
output record (written without processing).

What FastCS 0.14 does not offer yet, and so the one use of its private
names: an attribute's value set with an alarm. `AttrR.update(value)` takes
none and costs ~120 µs; `ValueRoute.post` sets what
`update()` sets for the attribute itself (`AttrR._value`, and the waiters
of `AttrR._on_update_events`) and puts the value into its record. Retired
by FastCS's `Update` (on its main branch): `attribute.update(Update(...))`.

softioc 4.7's autosave thread (`ioc.operator_settings`) is not a daemon,
and is told to stop only by an atexit handler, which Python runs after it
has joined every such thread: an IOC with autosave would never exit.
`stop_autosave` tells it (`Autosave._stop()`: it saves once more and ends)
when serving ends. Retired by softioc stopping the thread before the
interpreter joins it.

`check_installed()` runs at every IOC start: FastCS must be a version
pyproject.toml allows and still have those two names, else the IOC stops
with one line naming the package and version.
"""

from __future__ import annotations

import enum
import importlib
import importlib.metadata
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final, NamedTuple

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc import dbaccess

if TYPE_CHECKING:
    from fastcs.attributes import Attribute, AttrR

SUPPORTED: Final = {"fastcs": ((0, 14, 2), (0, 15))}
"""Package -> (lowest version, first version not supported), as in
pyproject.toml: the package whose private names this module uses."""
RBV_SUFFIX: Final = "_RBV"
MBB_STATES: Final = 16
"""An enum of up to this many members is an mbbi/mbbo, else a text record
(FastCS's rule)."""
TEXT_LENGTH: Final = 256
"""FastCS's text records hold this many characters (when the datatype says
no length), and a NUL."""


class Update(NamedTuple):
    """A value with its alarm (EPICS numbers)."""

    value: Any
    severity: int = 0
    status: int = 0
    message: str = ""


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


def record_names(attribute: Attribute[Any, Any]) -> tuple[str, str]:
    """(in record, out record) of `attribute`, "" where it has none."""
    from fastcs.attributes import AttrR, AttrW

    if not attribute.path:
        return "", ""
    name = ca_name(attribute)
    writes = isinstance(attribute, AttrW)
    reads = isinstance(attribute, AttrR)
    return (
        (name + RBV_SUFFIX if writes else name) if reads else "",
        name if writes else "",
    )


def database_records(attribute: Attribute[Any, Any], *, reads: bool) -> list[Any]:
    """The database records (epicsdbbuilder) of `attribute`'s out record, and
    in record if `reads`, to set fields on before the database is loaded."""
    from epicsdbbuilder import LookupRecord

    in_name, out_name = record_names(attribute)
    found = []
    for name in (out_name, in_name if reads else ""):
        if name:
            try:
                found.append(LookupRecord(name))
            except KeyError:  # not made (a name too long for EPICS)
                continue
    return found


def value_kind(datatype: Any) -> tuple[str, int, Callable[[Any], Any] | None]:
    """How a value of `datatype` goes into its record: (`dbaccess` kind,
    length, conversion or None), as FastCS's records of that datatype hold
    it."""
    from fastcs.datatypes import Bool, Enum, Float, Int, String, Waveform

    if isinstance(datatype, Float):
        return "double", 0, None
    if isinstance(datatype, Bool):
        return "enum", 0, int
    if isinstance(datatype, Int):
        return "long", 0, None
    if isinstance(datatype, Enum):
        if len(datatype.members) <= MBB_STATES:
            return "enum", 0, datatype.index_of
        return "text", TEXT_LENGTH + 1, lambda member: member.name
    if isinstance(datatype, String):
        return "text", (datatype.length or TEXT_LENGTH) + 1, None
    if isinstance(datatype, Waveform):
        return "array", int(datatype.shape[0]), None
    raise TypeError(f"no record holds a {type(datatype).__name__}")


class AttributeRecords:
    """The records serving one attribute, once the database serves."""

    __slots__ = ("attribute", "kind", "length", "readback", "setpoint", "to_record")

    def __init__(self, attribute: Attribute[Any, Any]) -> None:
        self.attribute = attribute
        self.kind, self.length, self.to_record = value_kind(attribute.datatype)
        in_name, out_name = record_names(attribute)
        self.readback = _record(in_name)
        """The in record (None: not made)."""
        self.setpoint = _record(out_name)
        """The out record of an output (None: not made, or not an output)."""

    def publish_alarm(
        self, severity: int, status: int, message: str = "", parts: Parts = Parts.ALL
    ) -> int:
        """Give the records of `parts` this alarm, value unchanged; how many
        were reached. The in record is processed with it (its own limits
        join it, its links see it), the out record is not."""
        reached = 0
        if self.readback is not None and Parts.READBACK in parts:
            with self.readback.locked():
                if severity:
                    self.readback.raise_alarm(severity, status, message)
                self.readback.process()
            reached += 1
        if self.setpoint is not None and Parts.SETPOINT in parts:
            self.setpoint.show_alarm(severity, status, message)
            reached += 1
        return reached

    def hold_setpoint(self) -> Callable[[], None]:
        """Lock the out record (if any) until the call returned is made."""
        record = self.setpoint
        if record is None:
            return _nothing
        return record.hold()

    def show_setpoint(self, value: Any) -> None:
        """Show `value` on the out record without processing it."""
        if self.setpoint is not None:
            convert = self.to_record
            shown = convert(value) if convert is not None else value
            self.setpoint.show_value(self.kind, shown, self.length)


def _nothing() -> None:
    """Nothing to undo."""


_records: dict[int, AttributeRecords] = {}
"""An attribute's records by its id (attributes live as long as the IOC)."""


def records_of(attribute: Attribute[Any, Any]) -> AttributeRecords:
    """The records of `attribute` (found once)."""
    found = _records.get(id(attribute))
    if found is None or found.attribute is not attribute:
        found = _records[id(attribute)] = AttributeRecords(attribute)
    return found


def _record(name: str) -> dbaccess.Record | None:
    if not name:
        return None
    try:
        return dbaccess.Record(name)
    except dbaccess.DbAccessError:
        return None


class ValueRoute:
    """Posts `Update`s of one attribute to its in record, once the database
    serves: one put, which EPICS processes (alarm limits, deadbands, links,
    CA and PVA monitors), its time the processing's; an update's severity is
    raised for that processing."""

    __slots__ = ("attribute", "records", "to_record", "write")

    def __init__(self, attribute: AttrR[Any, Any]) -> None:
        self.attribute = attribute
        self.records = records_of(attribute)
        self.to_record = self.records.to_record
        readback = self.records.readback
        self.write: Callable[[Any], None] | None = (
            readback.writer(self.records.kind, self.records.length)
            if readback is not None
            else None
        )

    def post(self, update: Update) -> None:
        """What `attribute.update(update)` will do: the value, then the record."""
        if update.severity:
            self.post_alarmed(
                update.value, update.severity, update.status, update.message
            )
        else:
            self.post_value(update.value)

    def post_value(self, value: Any) -> None:
        """`post` of a value without an alarm of its own (the hot path)."""
        attribute = self.attribute
        attribute._value = value  # pyright: ignore[reportPrivateUsage]
        if attribute._on_update_events:  # pyright: ignore[reportPrivateUsage]
            self._set_events(value)
        write = self.write
        if write is not None:
            convert = self.to_record
            write(value if convert is None else convert(value))

    def post_alarmed(
        self, value: Any, severity: int, status: int, message: str = ""
    ) -> None:
        """`post` of a value with this alarm raised for its processing."""
        attribute = self.attribute
        attribute._value = value  # pyright: ignore[reportPrivateUsage]
        if attribute._on_update_events:  # pyright: ignore[reportPrivateUsage]
            self._set_events(value)
        self.put(Update(value, severity, status, message))

    def _set_events(self, value: Any) -> None:
        """Wake who waits for this value, as `update()` does."""
        attribute = self.attribute
        events = attribute._on_update_events  # pyright: ignore[reportPrivateUsage]
        attribute._on_update_events = {e for e in events if not e.set(value)}  # pyright: ignore[reportPrivateUsage]

    def put(self, update: Update) -> None:
        """The record alone: `update`'s value, its severity raised for it."""
        write = self.write
        if write is None:
            return
        convert = self.to_record
        value = update.value
        shown = convert(value) if convert is not None else value
        if update.severity:
            readback: Any = self.records.readback
            with readback.locked():
                readback.raise_alarm(update.severity, update.status, update.message)
                write(shown)
        else:
            write(shown)


def follow_updates(attribute: AttrR[Any, Any]) -> None:
    """Put every value FastCS's own `update()` gives `attribute` into its
    record too (a FastCS on-update callback), at the time it is given: the
    IOC posts its values through `ValueRoute`, but an attribute may also be
    updated the FastCS way (a put to an output without IO, say)."""
    route: list[ValueRoute] = []

    async def to_record(value: Any) -> None:
        if not dbaccess.is_serving():
            return  # before iocInit: posted when the database serves
        if not route:
            route.append(ValueRoute(attribute))
        route[0].put(Update(value))

    attribute.add_on_update_callback(to_record)


def stop_autosave() -> None:
    """Let softioc's autosave thread end (see above); harmless without one."""
    from softioc.autosave import Autosave

    Autosave._stop()  # pyright: ignore[reportPrivateUsage]


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
    low, high = SUPPORTED[package]
    return f">={'.'.join(map(str, low))},<{'.'.join(map(str, high))}"


def version_problems() -> list[str]:
    """Installed versions outside the supported ranges, one text each."""
    problems: list[str] = []
    for package, (low, high) in SUPPORTED.items():
        try:
            installed = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            problems.append(f"{package} is not installed ({_range(package)})")
            continue
        if not low <= _version(installed) < high:
            problems.append(
                f"{package} {installed} is installed, fastcs-ethercat supports "
                f"{package}{_range(package)}"
            )
    return problems


def shape_problems() -> list[str]:
    """Private names used above that the installed FastCS no longer has."""
    from fastcs.attributes import AttrR
    from fastcs.datatypes import Int

    sample = AttrR(Int())
    return [
        f"fastcs: AttrR.{name} is gone"
        for name in ("_value", "_on_update_events")
        if not hasattr(sample, name)
    ]


def import_ioc_modules() -> None:
    """Import FastCS with its CA transport (once), EPICS without
    real-time threads (`scheduling`)."""
    import sys

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
    """Stop (`UserError`, one line) unless FastCS is a supported version
    with the private names this module uses."""
    problems = version_problems()
    if not problems:
        import_ioc_modules()
        problems = shape_problems()
    if problems:
        raise UserError(
            "; ".join(problems) + ": install the versions pyproject.toml names",
            where="packages",
        )
