"""An asyncio facade over pyads: one `pyads.Connection`, one worker thread.

pyads (Beckhoff's AdsLib underneath) blocks and is not thread-safe per
connection, so every pyads call of a connection runs on that connection's own
single-thread executor and the event loop only awaits it. Notifications arrive
on AdsLib's receive thread; their bytes are copied there and handed to the
loop with `call_soon_threadsafe`. Raw bytes that pyads returns (symbol and
data-type tables, sum reads) are decoded by the `ads` codec, the same code the
simulator encodes them with.

pyads' own failures become `AdsError` subclasses carrying the ADS return code.

Process-wide AdsLib facts this module relies on (Linux): the router lives in
the process; `Connection.open()` adds a route NetId -> `host[:port]` and a
second route to the same NetId through another address fails with 0x506
(ROUTERERR_PORTALREADYINUSE); the local NetId is one per process
(`set_local_net_id`). UDP discovery and add-route (pyads, port 48899) are not
tied to a connection and run in the default executor.
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import socket
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Final, TypeVar, cast

import pyads
from pyads.constants import ADSIGRP_SUMUP_READ
from pyads.pyads_ex import adsGetNetIdForPLC
from pyads.structs import SAdsNotificationHeader, SAdsSumRequest
from pydantic import SecretStr

from fastcs_ethercat.ads.commands import filetime_to_datetime
from fastcs_ethercat.ads.constants import (
    ADS_TCP_PORT,
    ADS_UDP_PORT,
    MAX_SUM_SUB_COMMANDS,
    AdsReturnCode,
    AdsState,
    IndexGroup,
    TransmissionMode,
    describe_return_code,
)
from fastcs_ethercat.ads.datatypes import AdsDataTypeEntry, decode_data_type_table
from fastcs_ethercat.ads.errors import AdsCodecError
from fastcs_ethercat.ads.netid import AmsNetId
from fastcs_ethercat.ads.sums import SumReadItem, SumReadResponse, chunked
from fastcs_ethercat.ads.symbols import (
    AdsSymbolEntry,
    SymbolUploadInfo2,
    decode_symbol_table,
)

logger = logging.getLogger(__name__)

_T = TypeVar("_T")
_UPLOAD_INFO_2_SIZE: Final = 24
_SYMBOL_ERRORS: Final = frozenset(
    {
        AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND,
        AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID,
        AdsReturnCode.DEVICE_SYMBOL_NOT_ACTIVE,
    }
)
_TIMEOUTS: Final = frozenset(
    {
        AdsReturnCode.CLIENT_SYNC_TIMEOUT,
        AdsReturnCode.DEVICE_TIMEOUT,
        AdsReturnCode.AMS_SYNC_TIMEOUT,
    }
)
_NOT_CONNECTED: Final = frozenset(
    {
        AdsReturnCode.CLIENT_PORT_NOT_OPEN,
        AdsReturnCode.CLIENT_NO_AMS_ADDR,
    }
)
_ROUTER_ERRORS: Final = range(0x500, 0x600)
"""AdsLib router errors (ROUTERERR_*, e.g. 0x506 port already in use)."""


# -- errors -----------------------------------------------------------------


class AdsError(Exception):
    """An ADS request failed; `code` is the ADS return code."""

    def __init__(self, code: int, operation: str, target: str, detail: str = ""):
        self.code = code
        self.operation = operation
        self.target = target
        text = f"{operation} on {target} failed: {describe_return_code(code)}"
        super().__init__(f"{text}: {detail}" if detail else text)


class AdsTimeoutError(AdsError):
    """No answer in time (0x745 from the client library, 0x719 from a device)."""


class AdsConnectionError(AdsError):
    """The target cannot be reached: AMS routing, router or port errors."""


class AdsSymbolError(AdsError):
    """A symbol is gone or changed (0x710, 0x711, 0x722): re-resolve symbols."""


class AdsProtocolError(AdsError):
    """The target answered with bytes that break the ADS layout."""


class AdsRouteError(AdsError):
    """The target refused to add our route (wrong user or password)."""


def unreachable(code: int) -> bool:
    """The code says the target did not answer (timeout, routing, router or
    port), rather than that it answered with an error."""
    if code in _TIMEOUTS:
        return True
    if code in _SYMBOL_ERRORS:
        return False
    return code < 0x700 or code in _NOT_CONNECTED or code in _ROUTER_ERRORS


def ads_error(code: int, operation: str, target: str, detail: str = "") -> AdsError:
    """The typed exception for an ADS return code."""
    kind: type[AdsError] = AdsError
    if code in _TIMEOUTS:
        kind = AdsTimeoutError
    elif code in _SYMBOL_ERRORS:
        kind = AdsSymbolError
    elif code < 0x700 or code in _NOT_CONNECTED or code in _ROUTER_ERRORS:
        kind = AdsConnectionError
    return kind(code, operation, target, detail)


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
    """One sample of a device notification, copied out of AdsLib's buffer."""

    handle: int
    timestamp: int
    """FILETIME: 100 ns ticks since 1601-01-01 UTC, as the target stamped it."""
    data: bytes

    @property
    def time(self) -> datetime:
        return filetime_to_datetime(self.timestamp)


@dataclass(frozen=True)
class NotificationHandle:
    """What `delete_notification` needs: the notification and user handles."""

    notification: int
    user: int | None


NotificationCallback = Callable[[Notification], object]
"""Called on the event loop's thread with each notification sample."""


# -- the client -------------------------------------------------------------


class AdsClient:
    """One ADS connection to `ams_net_id:ams_port` through `host[:tcp_port]`.

    Every method is a coroutine; pyads runs on this client's one worker thread.
    """

    def __init__(
        self,
        host: str,
        ams_net_id: str | AmsNetId,
        ams_port: int,
        *,
        tcp_port: int = ADS_TCP_PORT,
        timeout_ms: int | None = None,
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
        router_address = host if tcp_port == ADS_TCP_PORT else f"{host}:{tcp_port}"
        self._connection = pyads.Connection(str(netid), ams_port, router_address)
        self._executor = ThreadPoolExecutor(
            max_workers=1, thread_name_prefix=f"ads-{netid}:{ams_port}"
        )
        self._notifications: set[NotificationHandle] = set()
        self._closed = False

    @property
    def target(self) -> str:
        """`netid:port via host:tcp_port`, for messages."""
        return f"{self.ams_net_id}:{self.ams_port} via {self.host}:{self.tcp_port}"

    @property
    def is_open(self) -> bool:
        return self._connection.is_open

    def __repr__(self) -> str:
        return f"AdsClient({self.target})"

    async def __aenter__(self) -> AdsClient:
        await self.open()
        return self

    async def __aexit__(self, *_: object) -> None:
        await self.close()

    async def open(self) -> None:
        """Add the AdsLib route and open a local AMS port (no traffic yet)."""

        def open_connection() -> None:
            self._connection.open()
            if self.timeout_ms is not None:
                self._connection.set_timeout(self.timeout_ms)

        await self._call("open", open_connection)

    async def close(self) -> None:
        """Delete our notifications, close the connection, end the worker."""
        if self._closed:
            return
        self._closed = True

        def close_connection() -> None:
            for handle in list(self._notifications):
                try:
                    self._connection.del_device_notification(
                        handle.notification, _user_handle(handle)
                    )
                except pyads.ADSError as error:
                    logger.warning("%s: cannot delete notification: %s", self, error)
            self._notifications.clear()
            self._connection.close()

        # Requests still queued behind the running one are skipped (see
        # `_call`): closing waits for at most that one, never for a queue of
        # requests to a target that is gone, each until its timeout.
        loop = asyncio.get_running_loop()
        try:
            await loop.run_in_executor(self._executor, close_connection)
        except pyads.ADSError as error:
            logger.warning("%s: close: %s", self, error)
        finally:
            self._executor.shutdown(wait=False)

    async def read_state(self) -> AdsStatus:
        ads_state, device_state = await self._call(
            "read state", lambda: _opened(self._connection.read_state())
        )
        return AdsStatus(_ads_state(ads_state), device_state)

    async def read_device_info(self) -> DeviceInfo:
        name, version = await self._call(
            "read device info", lambda: _opened(self._connection.read_device_info())
        )
        return DeviceInfo(name, version.version, version.revision, version.build)

    async def read(self, index_group: int, index_offset: int, size: int) -> bytes:
        """Exactly `size` bytes (fewer from the target is an AdsProtocolError)."""
        return await self._call(
            f"read 0x{index_group:X}:0x{index_offset:X}",
            lambda: self._read(index_group, index_offset, size),
        )

    async def write(self, index_group: int, index_offset: int, data: bytes) -> None:
        def write() -> None:
            array_type = ctypes.c_ubyte * len(data)
            self._connection.write(
                index_group,
                index_offset,
                array_type.from_buffer_copy(data),
                array_type if data else None,
            )

        await self._call(f"write 0x{index_group:X}:0x{index_offset:X}", write)

    async def read_write(
        self,
        index_group: int,
        index_offset: int,
        read_size: int,
        data: bytes,
        *,
        exact: bool = True,
    ) -> bytes:
        """Write `data`, read back `read_size` bytes.

        With `exact=False` a shorter answer is accepted (pyads does not say how
        long it was): the bytes past it are zero, so the caller must know the
        layout's own length fields (a 0xF009 symbol entry, a string).
        """
        return await self._call(
            f"read-write 0x{index_group:X}:0x{index_offset:X}",
            lambda: self._read_write(index_group, index_offset, read_size, data, exact),
        )

    async def sum_read(
        self, items: Sequence[SumReadItem], chunk_size: int = MAX_SUM_SUB_COMMANDS
    ) -> list[bytes]:
        """Read many (group, offset, length) items with 0xF080 sum reads.

        Returns one raw answer per request of at most `chunk_size` items
        (n result u32 then every item's data), for the hot path to view with
        numpy; all requests of one call run back to back on the worker.
        """
        if not 0 < chunk_size <= MAX_SUM_SUB_COMMANDS:
            raise ValueError(f"chunk size must be 1..{MAX_SUM_SUB_COMMANDS}")
        chunks = [tuple(chunk) for chunk in chunked(items, chunk_size)]
        return await self._call(
            f"sum read of {len(items)} items",
            lambda: [self._sum_read_chunk(chunk) for chunk in chunks],
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

    async def read_list_by_name(
        self, names: Sequence[str], ads_sub_commands: int = MAX_SUM_SUB_COMMANDS
    ) -> dict[str, Any]:
        """pyads' `read_list_by_name`: values by symbol name, in sum requests.

        pyads looks up each new name once (0xF009) and caches it; an item that
        failed holds pyads' error text instead of a value.
        """
        return await self._call(
            f"read list of {len(names)} names",
            lambda: self._connection.read_list_by_name(
                list(names), ads_sub_commands=ads_sub_commands
            ),
        )

    async def upload_symbols(self) -> SymbolTables:
        """Upload 0xF00F (sizes), 0xF00B (symbols) and 0xF00E (data types)."""

        def upload() -> SymbolTables:
            info_raw = self._read(IndexGroup.SYM_UPLOAD_INFO_2, 0, _UPLOAD_INFO_2_SIZE)
            info = self._decode(
                "symbol upload", lambda: SymbolUploadInfo2.decode(info_raw)
            )
            symbols_raw = self._read(IndexGroup.SYM_UPLOAD, 0, info.symbol_table_size)
            types_raw = self._read(
                IndexGroup.SYM_DT_UPLOAD, 0, info.data_type_table_size
            )
            symbols = self._decode(
                "symbol upload",
                lambda: decode_symbol_table(symbols_raw, info.symbol_count),
            )
            data_types = self._decode(
                "data type upload",
                lambda: decode_data_type_table(types_raw, info.data_type_count),
            )
            return SymbolTables(info, symbols, data_types, symbols_raw, types_raw)

        return await self._call("symbol upload", upload)

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
        """Subscribe to (group, offset, size); `callback` runs on the loop."""
        loop = asyncio.get_running_loop()
        attributes = pyads.NotificationAttrib(
            size, int(mode), max_delay=max_delay_ms, cycle_time=cycle_time_ms
        )

        def on_notification(pointer: Any, _address: Any) -> None:
            # AdsLib's receive thread: copy the bytes now, they die on return.
            try:
                header = pointer.contents
                data = ctypes.string_at(
                    ctypes.addressof(header) + SAdsNotificationHeader.data.offset,
                    header.cbSampleSize,
                )
                sample = Notification(header.hNotification, header.nTimeStamp, data)
                loop.call_soon_threadsafe(callback, sample)
            except RuntimeError:
                pass  # the loop is closed: nobody is listening any more

        def add() -> NotificationHandle:
            handles = _opened(
                self._connection.add_device_notification(
                    (index_group, index_offset), attributes, on_notification
                )
            )
            handle = NotificationHandle(handles[0], handles[1])
            self._notifications.add(handle)
            return handle

        return await self._call(
            f"add notification 0x{index_group:X}:0x{index_offset:X}", add
        )

    async def delete_notification(self, handle: NotificationHandle) -> None:
        def delete() -> None:
            self._notifications.discard(handle)
            self._connection.del_device_notification(
                handle.notification, _user_handle(handle)
            )

        await self._call("delete notification", delete)

    # -- on the worker thread ----------------------------------------------

    def _read(self, index_group: int, index_offset: int, size: int) -> bytes:
        if size == 0:
            return b""
        raw = self._connection.read(
            index_group, index_offset, ctypes.c_ubyte * size, return_ctypes=True
        )
        return bytes(_opened(raw))

    def _read_write(
        self,
        index_group: int,
        index_offset: int,
        read_size: int,
        data: bytes,
        exact: bool,
    ) -> bytes:
        write_type = ctypes.c_ubyte * len(data)
        raw = self._connection.read_write(
            index_group,
            index_offset,
            ctypes.c_ubyte * read_size if read_size else None,
            write_type.from_buffer_copy(data),
            write_type if data else None,
            return_ctypes=True,
            check_length=exact,
        )
        return bytes(raw) if read_size else b""

    def _sum_read_chunk(self, chunk: Sequence[SumReadItem]) -> bytes:
        requests = (SAdsSumRequest * len(chunk))()
        for request, item in zip(requests, chunk, strict=True):
            request.iGroup = item.index_group
            request.iOffset = item.index_offset
            request.size = item.length
        raw = self._connection.read_write(
            ADSIGRP_SUMUP_READ, len(chunk), None, requests, None, return_ctypes=True
        )
        return bytes(_opened(raw))

    # -- plumbing ------------------------------------------------------------

    async def _call(self, operation: str, job: Callable[[], _T]) -> _T:
        loop = asyncio.get_running_loop()

        def unless_closed() -> _T:
            if self._closed:  # closed while this request waited its turn
                raise RuntimeError("cannot schedule new futures after shutdown")
            return job()

        try:
            return await loop.run_in_executor(self._executor, unless_closed)
        except pyads.ADSError as error:
            code = getattr(error, "err_code", AdsReturnCode.CLIENT_ERROR)
            raise ads_error(code, operation, self.target) from error
        except AdsError:
            raise
        except RuntimeError as error:
            raise self._runtime_error(operation, error) from error

    def _runtime_error(self, operation: str, error: RuntimeError) -> AdsError:
        text = str(error)
        if "Insufficient data" in text:
            return AdsProtocolError(
                AdsReturnCode.DEVICE_INVALID_SIZE, operation, self.target, text
            )
        if "after shutdown" in text:
            return AdsConnectionError(
                AdsReturnCode.CLIENT_PORT_NOT_OPEN, operation, self.target, "closed"
            )
        return AdsConnectionError(
            AdsReturnCode.CLIENT_PORT_NOT_OPEN, operation, self.target, text
        )

    def _decode(self, operation: str, decode: Callable[[], _T]) -> _T:
        try:
            return decode()
        except AdsCodecError as error:
            raise AdsProtocolError(
                error.return_code, operation, self.target, str(error)
            ) from error


def _opened(result: _T | None) -> _T:
    """pyads returns None instead of raising when the connection is not open."""
    if result is None:
        raise RuntimeError("the connection is not open")
    return result


def _user_handle(handle: NotificationHandle) -> int:
    """pyads types the user handle as int but takes None for "none to release"."""
    return cast(int, handle.user)


def _ads_state(value: int) -> AdsState | int:
    try:
        return AdsState(value)
    except ValueError:
        return value


# -- process-wide: local NetId, discovery, routes ---------------------------


def set_local_net_id(net_id: str | AmsNetId) -> None:
    """Set this process's AMS NetId (AdsLib's router is one per process)."""
    pyads.set_local_address(str(net_id))


def local_ip_towards(host: str) -> str:
    """The local IPv4 address the kernel would use to reach `host` (no traffic)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect((host, ADS_UDP_PORT))
        return str(probe.getsockname()[0])


async def discover_net_id(host: str) -> AmsNetId:
    """Ask `host` for its AMS NetId on UDP 48899 (pyads' `adsGetNetIdForPLC`)."""
    target = f"{host}:{ADS_UDP_PORT}"
    try:
        text = await asyncio.to_thread(adsGetNetIdForPLC, host)
    except TimeoutError as error:
        raise AdsTimeoutError(
            AdsReturnCode.CLIENT_SYNC_TIMEOUT, "NetId discovery", target
        ) from error
    except RuntimeError as error:
        raise AdsProtocolError(
            AdsReturnCode.DEVICE_INVALID_DATA, "NetId discovery", target, str(error)
        ) from error
    except OSError as error:
        raise AdsConnectionError(
            AdsReturnCode.TARGET_MACHINE_NOT_FOUND,
            "NetId discovery",
            target,
            error.strerror or str(error),
        ) from error
    return AmsNetId.parse(text)


async def add_route(
    host: str,
    *,
    local_net_id: str | AmsNetId,
    host_address: str,
    user: str,
    password: SecretStr,
    route_name: str | None = None,
) -> None:
    """Ask `host` to add a route back to us (pyads' `add_route_to_plc`).

    `host_address` is how the target reaches this host. The password leaves
    its `SecretStr` only inside the worker call; it is never logged and never
    part of an exception.
    """
    target = f"{host}:{ADS_UDP_PORT}"

    def add() -> bool:
        return pyads.add_route_to_plc(
            str(local_net_id),
            host_address,
            host,
            user,
            password.get_secret_value(),
            route_name=route_name or socket.gethostname(),
        )

    logger.info(
        "adding route %s -> %s on %s as %s", route_name, local_net_id, host, user
    )
    try:
        accepted = await asyncio.to_thread(add)
    except TimeoutError as error:
        raise AdsTimeoutError(
            AdsReturnCode.CLIENT_SYNC_TIMEOUT, "add route", target
        ) from error
    except RuntimeError as error:
        raise AdsRouteError(
            AdsReturnCode.DEVICE_INVALID_DATA, "add route", target, "unexpected reply"
        ) from error
    except OSError as error:
        raise AdsConnectionError(
            AdsReturnCode.TARGET_MACHINE_NOT_FOUND,
            "add route",
            target,
            error.strerror or str(error),
        ) from error
    if not accepted:
        raise AdsRouteError(
            AdsReturnCode.DEVICE_ACCESS_DENIED,
            "add route",
            target,
            f"user {user!r} or its password was refused",
        )
