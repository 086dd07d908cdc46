"""The IOC's EPICS database: FastCS's CA records made to behave as an EPICS
engineer expects, a site's own databases beside them, and iocInit, which
serves them on Channel Access (softioc's RSRV) and PV Access (QSRV, the
pvxs server softioc loads with `enable_pva`).

FastCS's CA transport makes one softioc record per PV, with the fields of
its attribute (DESC, EGU, PREC, states, lengths). Before the database is
loaded, with epicsdbbuilder's public record fields, each in record of an
attribute is made an ordinary EPICS input record whose value the IOC puts
(`ioc.dbaccess`, `ioc.fastcs_adapter.ValueRoute`):

- `DTYP "Soft Channel"`, `SCAN "Passive"`, no INP: a put to VAL processes
  the record in EPICS's own record support (alarm limits and HYST, MDEL and
  ADEL, SMOO, FLNK, the monitors of CP links), without Python per value;
- its time is the time it is processed (`TSE 0`), a few milliseconds after
  the ADS sum read that read the value. One time per poll cycle through
  `TSEL` (a link to one clock record the IOC sets to the read's time) was
  built and measured: EPICS puts every record linked so into one lock set,
  which cost a third of the update rate with a client monitoring (~80 000
  against ~113 000 updates/s at ~12 000 symbols) and a start-up that grows
  with the square of the records (1.5 s more at 500 terminals);
- FastCS's own `update()` of the attribute puts the value there too
  (`fastcs_adapter.follow_updates`);
- `DISP 0`: an operator may set alarm limits, deadbands and DESC (a put to
  VAL is overwritten by the next value, as on any input record);
- `HOPR`/`LOPR` from the datatype's range (FastCS puts the alarm limits
  there, which scaled values do not have), so meters and bars have a range;
  an output's too, beside the DRVL/DRVH FastCS gives it;
- state severities (`ZSV`/`OSV` of a bi, `ZRSV`... of an mbbi) from the
  datatype's table: a set Error bit is MAJOR by record support, and an
  operator may change it.

Every record also carries its PVI entry (`ioc.pvi`). `serve` does what
FastCS's own does (softioc's asyncio dispatcher, `builder.LoadDatabase`,
`softioc.iocInit`), and loads the site's `.db` files (the `databases` config
key) between the two, with their macros: their records can link to the
IOC's (`INPA "...:CH1:Value CP"`) as on any IOC.

One database serves both protocols, so a PV is the same record on CA and
PVA: its alarm limits, deadbands, access security and put audit apply to
both. Without CA, EPICS is told to start no CA server
(`EPICS_IOC_IGNORE_SERVERS=rsrv`); without PVA, softioc loads no QSRV.
"""

from __future__ import annotations

import asyncio
import os
import re
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from fastcs.attributes import AttrR, AttrW
from fastcs.datatypes import Float, Int
from fastcs.transports.epics import EpicsCAOptions
from fastcs.transports.epics.ca.transport import EpicsCATransport

from fastcs_ethercat.bounded import read_text_bounded
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.config import SiteDatabase
from fastcs_ethercat.ioc.datatypes import AlarmBool, AlarmEnum
from fastcs_ethercat.ioc.dbaccess import database_serves
from fastcs_ethercat.ioc.fastcs_adapter import RBV_SUFFIX, ca_name, follow_updates
from fastcs_ethercat.ioc.operator_settings import keep_operator_settings
from fastcs_ethercat.ioc.pvi import add_pvi_groups

if TYPE_CHECKING:
    from fastcs.controllers import ControllerAPI

MAX_DATABASE_BYTES: Final = 64 * 1024 * 1024
"""A site database larger than this is refused (a rack's is ~1 MB)."""
_STRING: Final = re.compile(r'"(?:[^"\\]|\\.)*"')
"""A quoted string of a database line."""
IGNORE_SERVERS: Final = "EPICS_IOC_IGNORE_SERVERS"
"""EPICS base: the servers iocInit does not start (`rsrv`: Channel Access)."""
SEVERITY_NAMES: Final = ("NO_ALARM", "MINOR", "MAJOR", "INVALID")
"""menuAlarmSevr, as a record field takes it."""
MBB_SEVERITY_FIELDS: Final = tuple(
    f"{prefix}SV"
    for prefix in (
        "ZR", "ON", "TW", "TH", "FR", "FV", "SX", "SV",
        "EI", "NI", "TE", "EL", "TV", "TT", "FT", "FF",
    )
)  # fmt: skip
"""An mbbi's state severities, in state order."""


_initialised: asyncio.Future[None] | None = None
"""Done once this process's iocInit has returned (softioc inits once)."""


@dataclass
class DatabaseTransport(EpicsCATransport):
    """FastCS's CA transport, its records with the fields above, the site's
    databases loaded after them."""

    site_databases: Sequence[SiteDatabase] = ()
    autosave_dir: Path | None = None
    """Where softioc's autosave keeps what operators set (`ioc.operator_settings`)."""
    autosave_name: str = "ioc"
    """The autosave file's name (the prefix)."""
    ca: bool = True
    """Serve Channel Access (RSRV)."""
    pva: bool = True
    """Serve PV Access (QSRV)."""
    _fields: RecordFields = field(default_factory=lambda: RecordFields())
    """The fields `connect` gives FastCS's records, loaded after them."""

    def connect(
        self, controller_apis: list[ControllerAPI], loop: asyncio.AbstractEventLoop
    ) -> None:
        super().connect(controller_apis, loop)
        if self.pva:
            add_pvi_groups(controller_apis)
        fields = self._fields = RecordFields()
        for api in controller_apis:
            for controller_api in api.walk_api():
                for attribute in controller_api.attributes.values():
                    if isinstance(attribute, AttrR) and attribute.enabled:
                        _as_an_input_record(attribute, fields)
                    if isinstance(attribute, AttrW) and attribute.enabled:
                        _as_an_output_record(attribute, fields)
        if self.autosave_dir is not None:
            keep_operator_settings(
                self.autosave_dir, self.autosave_name, controller_apis
            )

    async def serve(self) -> None:
        """Load the database, then the site's, then iocInit (on the loop, as
        FastCS does: EPICS's 0.5 s iocInit sleep is part of the start)."""
        from softioc import builder, softioc
        from softioc.asyncio_dispatcher import AsyncioDispatcher

        global _initialised
        loop = asyncio.get_running_loop()
        _initialised = done = loop.create_future()
        try:
            dispatcher = AsyncioDispatcher(loop)
            self._fields.load_defaults()
            builder.LoadDatabase()
            self._fields.load_changes()
            load_site_databases(self.site_databases)
            if not self.ca:
                os.environ[IGNORE_SERVERS] = "rsrv"
            softioc.iocInit(dispatcher, enable_pva=self.pva)
            database_serves()
        except Exception as error:
            done.set_exception(error)
            raise
        done.set_result(None)

    def __repr__(self) -> str:
        return f"Database{super().__repr__()}"


def database_transport(
    aliases: Mapping[str, str],
    site_databases: Sequence[SiteDatabase] = (),
    *,
    autosave_dir: Path | None = None,
    autosave_name: str = "ioc",
    ca: bool = True,
    pva: bool = True,
) -> DatabaseTransport:
    return DatabaseTransport(
        epicsca=EpicsCAOptions(aliases=dict(aliases)),
        site_databases=tuple(site_databases),
        autosave_dir=autosave_dir,
        autosave_name=autosave_name,
        ca=ca,
        pva=pva,
    )


def _as_an_input_record(attribute: AttrR[Any, Any], fields: RecordFields) -> None:
    """Give the in record of `attribute` the fields above (before the
    database is loaded)."""
    from epicsdbbuilder import LookupRecord

    name = ca_name(attribute)
    if isinstance(attribute, AttrW):
        name += RBV_SUFFIX
    try:
        record: Any = LookupRecord(name)
    except KeyError:  # not made (a name too long for EPICS: FastCS said so)
        return
    follow_updates(attribute)
    # fields back to EPICS's defaults (softioc's removed): a deletion is free,
    # and autosave (which restores MDEL) sets its own after these
    record.address = None  # INP: none, the IOC puts the value
    record.PINI = None
    record.MDEL = None  # EPICS's default (0: every change), not softioc's -1
    record.DISP = None  # EPICS's default (0: puts to fields allowed)
    changed = {"DTYP": "Soft Channel", "SCAN": "Passive"}
    changed.update(_display_range(attribute.datatype))
    record_type = type(record).__name__
    fields.change(record_type, name, changed)
    severities = _state_severities(attribute.datatype)
    if severities:  # defaults: FastCS's text and autosave's restore come after
        fields.default(record_type, name, severities)


def _state_severities(datatype: Any) -> dict[str, str]:
    """A bi's ZSV/OSV or an mbbi's state severities from the datatype's
    table (the record's alarm of its state, an operator may change it)."""
    if isinstance(datatype, AlarmBool):
        zero, one = datatype.severities
        return {"ZSV": SEVERITY_NAMES[zero], "OSV": SEVERITY_NAMES[one]}
    if isinstance(datatype, AlarmEnum) and len(datatype.members) <= len(
        MBB_SEVERITY_FIELDS
    ):
        return {
            field_name: SEVERITY_NAMES[severity]
            for field_name, severity in zip(
                MBB_SEVERITY_FIELDS, datatype.severities, strict=False
            )
            if severity
        }
    return {}


def _as_an_output_record(attribute: AttrW[Any, Any], fields: RecordFields) -> None:
    """An output's display range from its datatype's range (FastCS makes it
    DRVL/DRVH, the limits of what a put may ask for, and leaves LOPR/HOPR
    to alarm limits our values do not have)."""
    from epicsdbbuilder import LookupRecord

    name = ca_name(attribute)
    try:
        record: Any = LookupRecord(name)
    except KeyError:
        return
    changed = _display_range(attribute.datatype)
    if changed:
        fields.change(type(record).__name__, name, changed)


def _display_range(datatype: Any) -> dict[str, str]:
    """LOPR/HOPR from the range of a number's datatype, if it has one."""
    ranged = isinstance(datatype, Float | Int)
    if ranged and datatype.min is not None and datatype.max is not None:
        return {"LOPR": repr(datatype.min), "HOPR": repr(datatype.max)}
    return {}


class RecordFields:
    """Fields of the records FastCS makes, as database files EPICS parses
    (`record(TYPE, "NAME") { field(...) }` of a record already loaded
    changes its fields), not through epicsdbbuilder's check of each field,
    which costs ~0.1 ms a field: defaults loaded before FastCS's database
    (its text and autosave's restore, written into it, come after), and
    changes of FastCS's own fields loaded after it."""

    Records = list[tuple[str, str, dict[str, str]]]

    def __init__(self) -> None:
        self._defaults: RecordFields.Records = []
        self._changes: RecordFields.Records = []

    def default(self, record_type: str, name: str, fields: dict[str, str]) -> None:
        self._defaults.append((record_type, name, fields))

    def change(self, record_type: str, name: str, fields: dict[str, str]) -> None:
        self._changes.append((record_type, name, fields))

    def load_defaults(self) -> None:
        """Before FastCS's database."""
        _load(self._defaults, "defaults.db")

    def load_changes(self) -> None:
        """After FastCS's database, before iocInit."""
        _load(self._changes, "changes.db")


def _load(records: RecordFields.Records, name: str) -> None:
    if not records:
        return
    from softioc import softioc

    lines: list[str] = []
    for record_type, record, fields in records:
        lines.append(f'record({record_type}, "{_quoted(record)}") {{')
        lines += [f'    field({k}, "{_quoted(v)}")' for k, v in fields.items()]
        lines.append("}")
    with tempfile.TemporaryDirectory(prefix="fastcs-ethercat-") as folder:
        path = Path(folder) / name
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        softioc.dbLoadDatabase(str(path), None, None)


def _quoted(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')


def load_site_databases(databases: Iterable[SiteDatabase]) -> None:
    """Load each site database; a file EPICS cannot load stops the IOC with
    one line naming it (EPICS's own message is printed above it)."""
    from softioc import softioc

    for database in databases:
        check_closed(database.file)
        try:
            softioc.dbLoadDatabase(
                str(database.file), None, database.substitutions() or None
            )
        except Exception:
            raise UserError(
                "EPICS could not load this database (its message is above)",
                path=database.file,
            ) from None


def check_closed(path: Path) -> None:
    """Refuse a database whose braces do not close (strings and comments
    left out): EPICS 7.0's parser reads past the end of such a file and
    crashes the process instead of reporting it."""
    try:
        text = read_text_bounded(path, MAX_DATABASE_BYTES, what="database file")
    except OSError as error:
        raise UserError(f"cannot read it: {error.strerror}", path=path) from None
    depth = 0
    for number, line in enumerate(text.splitlines(), 1):
        code = _STRING.sub("", line).split("#", 1)[0]
        depth += code.count("{") - code.count("}")
        if depth < 0:
            raise UserError("a '}' closes nothing", path=path, where=f"line {number}")
    if depth:
        raise UserError("a '{' is never closed", path=path)


def set_callback_queue_size(entries: int) -> None:
    """EPICS callback queue entries (before iocInit): the default 2000
    overflows when thousands of records queue work at once (CP links, the
    put completions of a large rack)."""
    from fastcs_ethercat.ioc.dbaccess import set_callback_queue_size as set_size

    set_size(entries)


def failure() -> BaseException | None:
    """Why iocInit did not happen (for the launcher: FastCS logs a
    transport's exception and returns), None if it did or has not run."""
    if _initialised is None or not _initialised.done():
        return None
    return _initialised.exception()


async def initialised() -> None:
    """Once iocInit has returned (at once without a CA transport serving);
    call from a transport's `serve`, which starts after the CA one's."""
    if _initialised is not None:
        await asyncio.shield(_initialised)
