"""The asyncio ADS client: one target AMS address over a shared connection.

`AdsClient(host, net_id, port)` talks to one AMS address (a TwinCAT device
port, the I/O server, an EtherCAT master, a slave's mailbox) through an
`AmsTcpConnection` to the router at `host:tcp_port`: its own, or one shared
with other clients (`connection=`), which is how the IOC keeps one TCP
connection per PLC. Requests and answers are encoded and decoded by the
project's own codec, the same that the simulator speaks, and every answer is
checked in pure Python before it is used (`ads.session`): no byte from the
network reaches native code, so no byte can crash the process.

Failures are `AdsError` subclasses carrying the ADS return code
(`ads.errors`); a request never blocks the event loop.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Final, TypeVar

from fastcs_ethercat.ads.commands import (
    AddDeviceNotificationRequest,
    AddDeviceNotificationResponse,
    AdsRequest,
    AdsResponse,
    DeleteDeviceNotificationRequest,
    NotificationStamp,
    ReadDeviceInfoRequest,
    ReadDeviceInfoResponse,
    ReadRequest,
    ReadResponse,
    ReadStateRequest,
    ReadStateResponse,
    ReadWriteRequest,
    ReadWriteResponse,
    WriteRequest,
    filetime_to_datetime,
    notification_time_from_ms,
)
from fastcs_ethercat.ads.connection import AmsTcpConnection, set_local_net_id
from fastcs_ethercat.ads.constants import (
    ADS_TCP_PORT,
    MAX_SUM_SUB_COMMANDS,
    AdsReturnCode,
    AdsState,
    IndexGroup,
    TransmissionMode,
    describe_return_code,
)
from fastcs_ethercat.ads.datatypes import AdsDataTypeEntry, decode_data_type_table
from fastcs_ethercat.ads.errors import (
    AdsCodecError,
    AdsConnectionError,
    AdsConnectionLostError,
    AdsConnectionRefusedError,
    AdsConnectTimeoutError,
    AdsError,
    AdsHandleInvalidError,
    AdsHostUnreachableError,
    AdsProtocolError,
    AdsRouteError,
    AdsSymbolError,
    AdsTimeoutError,
    AdsUnknownHostError,
    ads_error,
    unreachable,
)
from fastcs_ethercat.ads.netid import AmsAddress, AmsNetId
from fastcs_ethercat.ads.ratelimit import RateLimitedLog
from fastcs_ethercat.ads.session import Answered
from fastcs_ethercat.ads.sums import (
    SumReadItem,
    SumReadLayout,
    SumReadRequest,
    SumReadResponse,
    SumReadWriteItem,
    SumReadWriteRequest,
    SumReadWriteResponse,
    SumWriteItem,
    SumWriteRequest,
    SumWriteResponse,
    chunked,
)
from fastcs_ethercat.ads.symbols import (
    SYMBOL_INFO_SIZE,
    AdsSymbolEntry,
    SymbolUploadInfo,
    SymbolUploadInfo2,
    decode_symbol_table,
    encode_symbol_name,
)
from fastcs_ethercat.ads.udp_client import add_route, discover_net_id, local_ip_towards
from fastcs_ethercat.ads.values import unpack_value
from fastcs_ethercat.ads.wire import U32, enum_or_int

logger = logging.getLogger(__name__)

_T = TypeVar("_T")
DEFAULT_TIMEOUT_MS: Final = 5000
"""Timeout of a request when none is given (AdsLib's default)."""
UPLOAD_INFO_2_SIZE: Final = 24
UPLOAD_INFO_SIZE: Final = 8
DATA_TYPE_TABLE_LIMIT: Final = 16 * 1024 * 1024
"""Read length of a data-type table whose size the target did not tell."""
NO_SUCH_SERVICE: Final = frozenset(
    {
        AdsReturnCode.DEVICE_SERVICE_NOT_SUPPORTED,
        AdsReturnCode.DEVICE_INVALID_GROUP,
        AdsReturnCode.DEVICE_INVALID_OFFSET,
    }
)
"""What a target answers a sum command it does not have: older TwinCAT 2,
pcdshub's ads-async, fastcs-catio's simulator and pyads' test server answer
0x701 (service not supported) or 0x702 / 0x703 (no such group or offset)."""
_SUM_NAMES: Final = {
    IndexGroup.SUMUP_READ: "sum reads (0xF080)",
    IndexGroup.SUMUP_WRITE: "sum writes (0xF081)",
    IndexGroup.SUMUP_READ_WRITE: "sum read-writes (0xF082)",
}
_refused_sums_said: set[tuple[str, int]] = set()
"""(target, sum group) whose refusal this process has logged: every new
connection decides again (the target may have changed), and says so again
only at debug level."""
REFUSED_SUMS_REMEMBERED: Final = 4096
"""Targets x groups remembered at most (a bound for a long-lived process)."""


# -- results ----------------------------------------------------------------


@dataclass(frozen=True)
class AdsStatus:
    """Answer of ReadState: the ADS state (5 = run) and the device state."""

    ads_state: AdsState | int
    device_state: int


@dataclass(frozen=True)
class DeviceInfo:
    """Answer of ReadDeviceInfo: the server's name and version."""

    name: str
    major: int
    minor: int
    build: int

    @property
    def version(self) -> str:
        return f"{self.major}.{self.minor}.{self.build}"


@dataclass(frozen=True)
class SymbolTables:
    """The target's symbol and data-type tables, raw and decoded."""

    info: SymbolUploadInfo2
    symbols: list[AdsSymbolEntry]
    data_types: list[AdsDataTypeEntry]
    raw_symbols: bytes
    raw_data_types: bytes


@dataclass(frozen=True)
class Notification:
    """One sample of a device notification."""

    handle: int
    timestamp: int
    """FILETIME: 100 ns ticks since 1601-01-01 UTC, as the target stamped it."""
    data: bytes

    @property
    def time(self) -> datetime:
        return filetime_to_datetime(self.timestamp)


@dataclass(frozen=True)
class NotificationHandle:
    """What `delete_notification` needs: the target's notification handle."""

    notification: int
    user: int | None = None


NotificationCallback = Callable[[Notification], object]
"""Called on the event loop's thread with each notification sample."""


@dataclass(frozen=True, slots=True)
class _Subscription:
    callback: NotificationCallback
    size: int


ItemResult = bytes | AdsError
"""Per item of a sum: its data, or the typed error of that item alone."""


# -- the client -------------------------------------------------------------


class AdsClient:
    """One ADS target address `ams_net_id:ams_port` behind `host[:tcp_port]`."""

    def __init__(
        self,
        host: str,
        ams_net_id: str | AmsNetId,
        ams_port: int,
        *,
        tcp_port: int = ADS_TCP_PORT,
        timeout_ms: int | None = None,
        connection: AmsTcpConnection | None = None,
    ) -> None:
        netid = (
            ams_net_id
            if isinstance(ams_net_id, AmsNetId)
            else AmsNetId.parse(ams_net_id)
        )
        self.host = host
        self.tcp_port = tcp_port
        self.ams_net_id = netid
        self.ams_port = ams_port
        self.timeout_ms = timeout_ms
        self.address = AmsAddress(netid, ams_port)
        self._owns_connection = connection is None
        self._connection = connection or AmsTcpConnection(host, tcp_port)
        self._port: int | None = None
        self._subscriptions: dict[int, _Subscription] = {}
        self._closed = False
        self._log = RateLimitedLog(logger)
        self._no_sums: set[int] = set()
        """Sum groups this target refused on this connection: their items go
        as single requests until the connection is lost (decided once)."""

    @property
    def target(self) -> str:
        """`netid:port via host:tcp_port`, for messages."""
        return f"{self.address} via {self.host}:{self.tcp_port}"

    @property
    def connection(self) -> AmsTcpConnection:
        """The connection this client's requests travel on."""
        return self._connection

    @property
    def timeout_s(self) -> float:
        return (self.timeout_ms or DEFAULT_TIMEOUT_MS) / 1000.0

    def __repr__(self) -> str:
        return f"AdsClient({self.target})"

    async def __aenter__(self) -> AdsClient:
        await self.open()
        return self

    async def __aexit__(self, *_: object) -> None:
        await self.close()

    async def open(self) -> None:
        """Take a local AMS port and connect (raises why the target cannot be
        reached; later requests connect again by themselves after a loss)."""
        if self._closed:
            raise self._closed_error("open")
        if self._port is None:
            self._port = self._connection.open_port(self)
        await self._connection.connect()

    async def close(self) -> None:
        """Delete our notifications, release our port; requests still in
        flight fail at once (a stalled target is not waited for)."""
        if self._closed:
            return
        self._closed = True
        port, self._port = self._port, None
        if port is not None:
            handles = list(self._subscriptions)
            self._subscriptions.clear()
            if handles and self._connection.connected:
                await self._delete_quietly(port, handles)
            self._connection.close_port(port)
        if self._owns_connection:
            await self._connection.close()

    # -- plain services ------------------------------------------------------

    async def read_state(self) -> AdsStatus:
        response = await self._request(
            "read state", ReadStateRequest(), ReadStateResponse
        )
        return AdsStatus(
            enum_or_int(AdsState, response.ads_state), response.device_state
        )

    async def read_device_info(self) -> DeviceInfo:
        response = await self._request(
            "read device info", ReadDeviceInfoRequest(), ReadDeviceInfoResponse
        )
        return DeviceInfo(response.name, response.major, response.minor, response.build)

    async def read(
        self, index_group: int, index_offset: int, size: int, *, exact: bool = True
    ) -> bytes:
        """`size` bytes; with `exact=False` up to `size` (names, strings, tables
        whose length is not known in advance)."""
        operation = f"read 0x{index_group:X}:0x{index_offset:X}"
        if size == 0:
            return b""
        response = await self._request(
            operation, ReadRequest(index_group, index_offset, size), ReadResponse
        )
        return self._sized(operation, response.data, size, exact)

    async def write(self, index_group: int, index_offset: int, data: bytes) -> None:
        await self._request(
            f"write 0x{index_group:X}:0x{index_offset:X}",
            WriteRequest(index_group, index_offset, bytes(data)),
            AdsResponse,
        )

    async def read_write(
        self,
        index_group: int,
        index_offset: int,
        read_size: int,
        data: bytes,
        *,
        exact: bool = True,
    ) -> bytes:
        """Write `data`, read back `read_size` bytes (up to, with `exact=False`)."""
        request = ReadWriteRequest(index_group, index_offset, read_size, bytes(data))
        return await self._read_write(request, exact)

    async def _read_write(self, request: ReadWriteRequest, exact: bool) -> bytes:
        operation = f"read-write 0x{request.index_group:X}:0x{request.index_offset:X}"
        response = await self._request(operation, request, ReadWriteResponse)
        return self._sized(operation, response.data, request.read_length, exact)

    async def _sums(
        self,
        group: IndexGroup,
        requests: Sequence[SumReadRequest | SumWriteRequest | SumReadWriteRequest],
        exact: bool = True,
    ) -> list[bytes] | None:
        """Every sum request (of sum `group`) as its ReadWrite (the item count
        as offset), all in flight at once; None where the target has no such
        sum command (then the caller sends the items one by one)."""
        if group in self._no_sums:
            return None
        try:
            return await _all(
                self._read_write(r.to_read_write(), exact) for r in requests
            )
        except AdsError as error:
            if error.code not in NO_SUCH_SERVICE:
                raise
            self._no_sums.add(group)
            logger.log(
                self._refused_sums_level(group),
                "target %s has no %s (%s): single requests",
                self.target,
                _SUM_NAMES.get(group, f"sum 0x{group:X}"),
                describe_return_code(error.code),
            )
            return None

    def _refused_sums_level(self, group: int) -> int:
        """Said once per target and group in a process; later (a reconnect,
        another client) at debug level. TwinCAT's EtherCAT device port has
        no sum writes: expected, so never a warning."""
        said = (self.target, group)
        if said in _refused_sums_said:
            return logging.DEBUG
        if len(_refused_sums_said) < REFUSED_SUMS_REMEMBERED:
            _refused_sums_said.add(said)
        return logging.INFO if group == IndexGroup.SUMUP_WRITE else logging.WARNING

    # -- sum commands ----------------------------------------------------------

    async def sum_read(
        self, items: Sequence[SumReadItem], chunk_size: int = MAX_SUM_SUB_COMMANDS
    ) -> list[bytes]:
        """Read many (group, offset, length) items with 0xF080 sum reads.

        Returns one raw answer per request of at most `chunk_size` items
        (n results u32 then every item's data, `SumReadLayout`), for the hot
        path to view with numpy; the requests are all in flight at once.
        """
        if not 0 < chunk_size <= MAX_SUM_SUB_COMMANDS:
            raise ValueError(f"chunk size must be 1..{MAX_SUM_SUB_COMMANDS}")
        chunks = [tuple(c) for c in chunked(items, chunk_size)]
        answers = await self._sums(
            IndexGroup.SUMUP_READ, [SumReadRequest(c) for c in chunks]
        )
        if answers is not None:
            return answers
        return [await self._single_reads(chunk) for chunk in chunks]

    async def _single_reads(self, items: Sequence[SumReadItem]) -> bytes:
        """The answer a 0xF080 sum read of `items` would give, from single
        reads all in flight at once (a target without sum reads)."""

        async def one(item: SumReadItem) -> tuple[int, bytes]:
            try:
                return AdsReturnCode.NO_ERROR, await self.read(
                    item.index_group, item.index_offset, item.length
                )
            except AdsError as error:
                if unreachable(error.code):
                    raise
                return error.code, b""

        outcomes = await _all(one(item) for item in items)
        return SumReadLayout.of(items).encode(
            [result for result, _ in outcomes], [data for _, data in outcomes]
        )

    async def sum_read_items(
        self, items: Sequence[SumReadItem], chunk_size: int = MAX_SUM_SUB_COMMANDS
    ) -> list[tuple[int, bytes]]:
        """Like `sum_read`, decoded: (result, data) per item, in item order."""
        answers = await self.sum_read(items, chunk_size)
        outcomes: list[tuple[int, bytes]] = []
        for chunk, answer in zip(chunked(items, chunk_size), answers, strict=True):
            response = self._decode(
                "sum read",
                lambda c=chunk, a=answer: SumReadResponse.decode(
                    a, [item.length for item in c]
                ),
            )
            outcomes.extend(zip(response.results, response.data, strict=True))
        return outcomes

    async def sum_read_write(
        self, items: Sequence[SumReadWriteItem]
    ) -> list[tuple[int, bytes]]:
        """0xF082 in requests of at most 500: (result, data) per item."""
        requests = [SumReadWriteRequest(tuple(c)) for c in chunked(items)]
        answers = await self._sums(IndexGroup.SUMUP_READ_WRITE, requests, exact=False)
        if answers is None:
            return await self._single_read_writes(items)
        outcomes: list[tuple[int, bytes]] = []
        for request, answer in zip(requests, answers, strict=True):
            response = self._decode(
                "sum read-write",
                lambda r=request, a=answer: SumReadWriteResponse.decode(
                    a, len(r.items)
                ),
            )
            outcomes.extend(zip(response.results, response.data, strict=True))
        return outcomes

    async def _single_read_writes(
        self, items: Sequence[SumReadWriteItem]
    ) -> list[tuple[int, bytes]]:
        """(result, data) per item as single ReadWrites, all in flight at once."""

        async def one(item: SumReadWriteItem) -> tuple[int, bytes]:
            try:
                return AdsReturnCode.NO_ERROR, await self.read_write(
                    item.index_group,
                    item.index_offset,
                    item.read_length,
                    item.data,
                    exact=False,
                )
            except AdsError as error:
                if unreachable(error.code):
                    raise
                return error.code, b""

        return await _all(one(item) for item in items)

    async def sum_write(self, items: Sequence[SumWriteItem]) -> list[int]:
        """0xF081 in requests of at most 500: the result of each item.

        A target that refuses sum writes (TwinCAT's EtherCAT device port
        answers 0x701) gets the items as single writes, all in flight at once.
        """
        requests = [SumWriteRequest(tuple(c)) for c in chunked(items)]
        answers = await self._sums(IndexGroup.SUMUP_WRITE, requests)
        if answers is None:
            return await self._single_writes(items)
        results: list[int] = []
        for request, answer in zip(requests, answers, strict=True):
            response = self._decode(
                "sum write",
                lambda r=request, a=answer: SumWriteResponse.decode(a, len(r.items)),
            )
            results.extend(response.results)
        return results

    async def _single_writes(self, items: Sequence[SumWriteItem]) -> list[int]:
        async def one(item: SumWriteItem) -> int:
            try:
                await self.write(item.index_group, item.index_offset, item.data)
            except AdsError as error:
                if unreachable(error.code):
                    raise
                return error.code
            return AdsReturnCode.NO_ERROR

        return await _all(one(item) for item in items)

    # -- symbols by handle -----------------------------------------------------

    async def acquire_handles(self, names: Sequence[str]) -> list[int | AdsError]:
        """A handle per symbol name (0xF003 in 0xF082 sums): per name the
        handle, or that name's own error (AdsSymbolError: no such symbol)."""
        outcomes = await self.sum_read_write(
            [
                SumReadWriteItem(
                    IndexGroup.SYM_HANDLE_BY_NAME, 0, 4, encode_symbol_name(n)
                )
                for n in names
            ]
        )
        handles: list[int | AdsError] = []
        for name, (result, data) in zip(names, outcomes, strict=True):
            if result != AdsReturnCode.NO_ERROR:
                handles.append(ads_error(result, f"handle of {name!r}", self.target))
            elif len(data) != U32.size:
                handles.append(
                    AdsProtocolError(
                        AdsReturnCode.CLIENT_SYNC_RES_INVALID,
                        f"handle of {name!r}",
                        self.target,
                        f"a handle is 4 bytes, got {len(data)}",
                    )
                )
            else:
                handles.append(int(U32.unpack(data)[0]))
        return handles

    async def read_by_handles(
        self, reads: Sequence[tuple[int, int]]
    ) -> list[ItemResult]:
        """Values of (handle, size) pairs in 0xF080 sums of 0xF005 items: per
        item its bytes or its own error (AdsHandleInvalidError: acquire the
        handle again)."""
        outcomes = await self.sum_read_items(
            [SumReadItem(IndexGroup.SYM_VALUE_BY_HANDLE, h, size) for h, size in reads]
        )
        errors = self._handle_errors("read", [h for h, _ in reads], outcomes)
        return [
            data if error is None else error
            for (_, data), error in zip(outcomes, errors, strict=True)
        ]

    async def read_by_handle(self, handle: int, size: int) -> bytes:
        """One value by handle (0xF005, offset = handle); fewer bytes than the
        symbol holds give its first bytes."""
        operation = f"read of handle 0x{handle:X}"
        response = await self._request(
            operation,
            ReadRequest(IndexGroup.SYM_VALUE_BY_HANDLE, handle, size),
            ReadResponse,
            by_handle=True,
        )
        return self._sized(operation, response.data, size, exact=True)

    async def write_by_handle(self, handle: int, data: bytes) -> None:
        """Write one value by handle; a size other than the symbol's is
        refused by the target (0x705), an invalid handle raises
        AdsHandleInvalidError."""
        await self._request(
            f"write of handle 0x{handle:X}",
            WriteRequest(IndexGroup.SYM_VALUE_BY_HANDLE, handle, bytes(data)),
            AdsResponse,
            by_handle=True,
        )

    async def release_handles(self, handles: Sequence[int]) -> list[AdsError | None]:
        """Release handles (0xF006 items of a 0xF081 sum, or single writes):
        per handle None or its own error."""
        results = await self.sum_write(
            [
                SumWriteItem(IndexGroup.SYM_RELEASE_HANDLE, 0, U32.pack(h))
                for h in handles
            ]
        )
        return self._handle_errors("release", handles, results)

    def _handle_errors(
        self,
        verb: str,
        handles: Sequence[int],
        outcomes: Sequence[int] | Sequence[tuple[int, bytes]],
    ) -> list[AdsError | None]:
        """Per item of a sum by handle: None, or its typed error."""
        errors: list[AdsError | None] = []
        for handle, outcome in zip(handles, outcomes, strict=True):
            result = outcome if isinstance(outcome, int) else outcome[0]
            errors.append(
                None
                if result == AdsReturnCode.NO_ERROR
                else ads_error(
                    result,
                    f"{verb} of handle 0x{handle:X}",
                    self.target,
                    by_handle=True,
                )
            )
        return errors

    # -- symbols by name and the tables ----------------------------------------------

    async def read_list_by_name(
        self, names: Sequence[str], ads_sub_commands: int = MAX_SUM_SUB_COMMANDS
    ) -> dict[str, Any]:
        """Values by symbol name, as pyads' `read_list_by_name` gives them:
        each name's entry (0xF009 in 0xF082 sums), then 0xF080 sum reads; a
        name that failed maps to its error's text instead of a value."""
        infos = await self.sum_read_write(
            [
                SumReadWriteItem(
                    IndexGroup.SYM_INFO_BY_NAME_EX,
                    0,
                    SYMBOL_INFO_SIZE,
                    encode_symbol_name(name),
                )
                for name in names
            ]
        )
        values: dict[str, Any] = {}
        found: list[tuple[str, AdsSymbolEntry]] = []
        for name, (result, data) in zip(names, infos, strict=True):
            if result != AdsReturnCode.NO_ERROR:
                values[name] = str(ads_error(result, f"info of {name!r}", self.target))
                continue
            entry = self._decode("symbol info", lambda d=data: _entry(d))
            found.append((name, entry))
        outcomes = await self.sum_read_items(
            [
                SumReadItem(entry.index_group, entry.index_offset, entry.size)
                for _, entry in found
            ],
            ads_sub_commands,
        )
        for (name, entry), (result, data) in zip(found, outcomes, strict=True):
            if result != AdsReturnCode.NO_ERROR:
                values[name] = str(ads_error(result, f"read of {name!r}", self.target))
                continue
            try:
                values[name] = unpack_value(entry.type_name, data)
            except AdsCodecError:
                values[name] = data
        return {name: values[name] for name in names}

    async def read_symbol_version(self) -> int | None:
        """The symbol version (0xF008), or None where the port does not
        answer it (an I/O device port may not: never rely on it alone)."""
        try:
            return (await self.read(IndexGroup.SYM_VERSION, 0, 1))[0]
        except (AdsConnectionError, AdsTimeoutError, AdsProtocolError):
            raise
        except AdsError as error:
            logger.debug("%s: no symbol version: %s", self, error)
            return None

    async def upload_symbols(self) -> SymbolTables:
        """The symbol table (0xF00B) and data-type table (0xF00E).

        Their sizes come from 0xF00F (24 bytes; a shorter answer is used for
        the fields it has, at least the first 8: symbol count and table
        size); a target that does not answer it, or answers fewer than 8
        bytes, is asked 0xF00C (those 8 bytes alone); a data-type table whose
        size is not known is read as far as it goes, or left empty if the
        target has none.
        """
        info = await self._upload_info()
        symbols_raw = await self.read(IndexGroup.SYM_UPLOAD, 0, info.symbol_table_size)
        symbols = self._decode(
            "symbol upload", lambda: decode_symbol_table(symbols_raw, info.symbol_count)
        )
        types_raw = await self._data_type_table(info)
        data_types = self._decode(
            "data type upload",
            lambda: decode_data_type_table(
                types_raw, info.data_type_count if info.data_type_table_size else None
            ),
        )
        if not info.data_type_table_size:
            info = SymbolUploadInfo2(
                info.symbol_count,
                info.symbol_table_size,
                len(data_types),
                len(types_raw),
            )
        return SymbolTables(info, symbols, data_types, symbols_raw, types_raw)

    async def _read_if_served(self, index_group: int, size: int, what: str) -> bytes:
        """Up to `size` bytes at offset 0 of `index_group`; b"" when the target
        answers that it does not serve it (one that does not answer raises)."""
        try:
            return await self.read(index_group, 0, size, exact=False)
        except (AdsConnectionError, AdsTimeoutError):
            raise
        except AdsError as error:
            logger.debug("%s: no %s: %s", self, what, error)
            return b""

    async def _upload_info(self) -> SymbolUploadInfo2:
        raw = await self._read_if_served(
            IndexGroup.SYM_UPLOAD_INFO_2, UPLOAD_INFO_2_SIZE, "upload info 2 (0xF00F)"
        )
        if len(raw) >= UPLOAD_INFO_2_SIZE:
            return self._decode("symbol upload", lambda: SymbolUploadInfo2.decode(raw))
        if len(raw) >= UPLOAD_INFO_SIZE:  # short, as some targets answer
            return _short_upload_info(raw)
        old = await self.read(IndexGroup.SYM_UPLOAD_INFO, 0, UPLOAD_INFO_SIZE)
        info = self._decode("symbol upload", lambda: SymbolUploadInfo.decode(old))
        return SymbolUploadInfo2(info.symbol_count, info.symbol_table_size)

    async def _data_type_table(self, info: SymbolUploadInfo2) -> bytes:
        if info.data_type_table_size:
            return await self.read(
                IndexGroup.SYM_DT_UPLOAD, 0, info.data_type_table_size
            )
        return await self._read_if_served(
            IndexGroup.SYM_DT_UPLOAD, DATA_TYPE_TABLE_LIMIT, "data-type table"
        )

    # -- notifications -------------------------------------------------------------

    async def add_notification(
        self,
        index_group: int,
        index_offset: int,
        size: int,
        callback: NotificationCallback,
        *,
        mode: TransmissionMode = TransmissionMode.SERVER_ON_CHANGE,
        cycle_time_ms: float = 10.0,
        max_delay_ms: float = 0.0,
    ) -> NotificationHandle:
        """Subscribe to (group, offset, size); `callback` runs on the loop.

        The handle is registered the moment its answer is read, before any
        later frame: the first sample always finds its callback.
        """
        request = AddDeviceNotificationRequest(
            index_group,
            index_offset,
            size,
            int(mode),
            notification_time_from_ms(max_delay_ms),
            notification_time_from_ms(cycle_time_ms),
        )

        def register(answer: Answered) -> None:
            response = answer.response
            if (
                not answer.packet.error_code
                and isinstance(response, AddDeviceNotificationResponse)
                and response.result == AdsReturnCode.NO_ERROR
                and not self._closed
            ):
                self._subscriptions[response.handle] = _Subscription(callback, size)

        response = await self._request(
            f"add notification 0x{index_group:X}:0x{index_offset:X}",
            request,
            AddDeviceNotificationResponse,
            on_answer=register,
        )
        return NotificationHandle(response.handle)

    async def delete_notification(self, handle: NotificationHandle) -> None:
        self._subscriptions.pop(handle.notification, None)
        await self._request(
            "delete notification",
            DeleteDeviceNotificationRequest(handle.notification),
            AdsResponse,
        )

    def notified(
        self, source: AmsAddress, stamps: tuple[NotificationStamp, ...]
    ) -> None:
        """Samples the connection received for our port (on the loop)."""
        if source != self.address:
            return
        for stamp in stamps:
            for sample in stamp.samples:
                subscription = self._subscriptions.get(sample.handle)
                if subscription is None:
                    continue  # deleted, or never ours
                if len(sample.data) > subscription.size:
                    self._log.warning(
                        "oversize",
                        "%s: notification %d carries %d bytes for %d: dropped",
                        self,
                        sample.handle,
                        len(sample.data),
                        subscription.size,
                    )
                    continue
                notification = Notification(sample.handle, stamp.timestamp, sample.data)
                try:
                    subscription.callback(notification)
                except Exception:
                    logger.exception("%s: notification callback failed", self)

    def connection_lost(self) -> None:
        """The target forgot our notifications with the connection; what it
        serves is decided again on the next (it may be another target)."""
        self._no_sums.clear()
        if self._subscriptions:
            logger.warning(
                "%s: connection lost, %d notifications gone",
                self,
                len(self._subscriptions),
            )
            self._subscriptions.clear()

    # -- plumbing --------------------------------------------------------------

    async def _request(
        self,
        operation: str,
        request: AdsRequest,
        expected: type[_Response],
        *,
        on_answer: Callable[[Answered], object] | None = None,
        by_handle: bool = False,
    ) -> _Response:
        if self._closed:
            raise self._closed_error(operation)
        port = self._port
        if port is None:  # not opened: the first request takes the port
            port = self._port = self._connection.open_port(self)
        answer = await self._connection.request(
            self.address,
            port,
            request,
            timeout_s=self.timeout_s,
            operation=operation,
            who=self.target,
            on_answer=on_answer,
        )
        if answer.packet.error_code != AdsReturnCode.NO_ERROR:
            raise ads_error(answer.packet.error_code, operation, self.target)
        response = answer.response
        if response is None:
            raise AdsProtocolError(
                AdsReturnCode.CLIENT_SYNC_RES_INVALID,
                operation,
                self.target,
                "empty answer",
            )
        if response.result != AdsReturnCode.NO_ERROR:
            raise ads_error(
                response.result, operation, self.target, by_handle=by_handle
            )
        if not isinstance(response, expected):
            raise AdsProtocolError(
                AdsReturnCode.CLIENT_SYNC_RES_INVALID,
                operation,
                self.target,
                f"a {type(response).__name__} answered",
            )
        return response

    def _sized(self, operation: str, data: bytes, size: int, exact: bool) -> bytes:
        if exact and len(data) != size:
            raise AdsProtocolError(
                AdsReturnCode.DEVICE_INVALID_SIZE,
                operation,
                self.target,
                f"{len(data)} bytes answered, {size} asked for",
            )
        return data

    def _decode(self, operation: str, decode: Callable[[], _T]) -> _T:
        try:
            return decode()
        except AdsCodecError as error:
            raise AdsProtocolError(
                error.return_code, operation, self.target, str(error)
            ) from error

    def _closed_error(self, operation: str) -> AdsConnectionError:
        return AdsConnectionError(
            AdsReturnCode.CLIENT_PORT_NOT_OPEN, operation, self.target, "closed"
        )

    async def _delete_quietly(self, port: int, handles: list[int]) -> None:
        """Delete notifications on close, briefly: a dead target is not
        waited for (the connection forgets them anyway)."""

        async def delete(handle: int) -> None:
            await self._connection.request(
                self.address,
                port,
                DeleteDeviceNotificationRequest(handle),
                timeout_s=min(self.timeout_s, 1.0),
                operation="delete notification",
                who=self.target,
            )

        results = await asyncio.gather(
            *(delete(h) for h in handles), return_exceptions=True
        )
        failed = [r for r in results if isinstance(r, BaseException)]
        if failed:
            logger.debug(
                "%s: %d notifications not deleted: %s", self, len(failed), failed[0]
            )


_Response = TypeVar("_Response", bound=AdsResponse)


async def _all(awaitables: Any) -> list[Any]:
    """Await all at once (one directly); the first error is raised once
    every one has finished."""
    pending = list(awaitables)
    if len(pending) == 1:
        return [await pending[0]]
    results = await asyncio.gather(*pending, return_exceptions=True)
    for result in results:
        if isinstance(result, BaseException):
            raise result
    return results


def _short_upload_info(raw: bytes) -> SymbolUploadInfo2:
    """A 0xF00F answer shorter than 24 bytes: its first 8 are what the upload
    needs (symbol count and table size, all pyads and fastcs-catio read), the
    data-type count and size follow where the answer has them."""
    fields = [int(U32.unpack_from(raw, 4 * n)[0]) for n in range(len(raw) // 4)]
    return SymbolUploadInfo2(*fields[:4])


def _entry(data: bytes) -> AdsSymbolEntry:
    entry, _ = AdsSymbolEntry.decode_at(data)
    return entry


__all__ = [
    "AdsClient",
    "AdsConnectTimeoutError",
    "AdsConnectionError",
    "AdsConnectionLostError",
    "AdsConnectionRefusedError",
    "AdsError",
    "AdsHandleInvalidError",
    "AdsHostUnreachableError",
    "AdsProtocolError",
    "AdsRouteError",
    "AdsStatus",
    "AdsSymbolError",
    "AdsTimeoutError",
    "AdsUnknownHostError",
    "DeviceInfo",
    "ItemResult",
    "Notification",
    "NotificationCallback",
    "NotificationHandle",
    "SymbolTables",
    "add_route",
    "ads_error",
    "discover_net_id",
    "local_ip_towards",
    "set_local_net_id",
    "unreachable",
]
