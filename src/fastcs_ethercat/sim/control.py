"""Control the running simulator: counters, process-image values, faults.

`SimControl` is the Python API for in-process tests; `ControlHttpServer`
offers the same operations as a small HTTP/JSON API on loopback for tests in
another process (stdlib asyncio only, one request per connection):

    GET    /counters           requests per command and index group, total
    DELETE /counters           reset the counters
    GET    /symbols/{name}     {"name": ..., "value": ...}
    PUT    /symbols/{name}     body {"value": ...}: force a value
    GET    /faults             the faults in force
    POST   /faults             body {"kind": ..., ...parameters}; 400 for a
                               bad kind, bad parameters or unknown symbols
    DELETE /faults             clear every fault
    GET    /status             NetId, ports, connections, the model

`{name}` is the TwinCAT symbol name, URL-encoded ("Term%201%20(EK1100).ID").
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from http import HTTPStatus
from typing import Any, Final, Protocol, TypeVar
from urllib.parse import unquote, urlsplit

from fastcs_ethercat.loopback import LOOPBACK
from fastcs_ethercat.sim.faults import Fault, FaultError, FaultKind, parse_fault
from fastcs_ethercat.sim.server import AmsServer

log = logging.getLogger(__name__)

MAX_BODY_SIZE: Final = 1024 * 1024
HEADER_TIMEOUT_SECONDS: Final = 10.0
CALL_TIMEOUT_SECONDS: Final = 30.0

_T = TypeVar("_T")


class ControllableTarget(Protocol):
    """The model operations the control API reaches (`twincat.target.SimTarget`)."""

    def get_symbol_value(self, name: str) -> Any: ...

    def set_symbol_value(self, name: str, value: Any) -> Any: ...

    def set_slave_state(
        self,
        address_or_name: int | str | None,
        state: int | str,
        device: int | None = None,
    ) -> Any: ...

    def set_link_lost(
        self, address_or_name: int | str | None, lost: bool, device: int | None = None
    ) -> Any: ...

    def online_change(
        self,
        pdo_groups: Mapping[str, str] | None = None,
        removed: Sequence[str] = (),
    ) -> Any: ...

    def set_run_state(self, running: bool) -> Any: ...

    def force_error(self, code: int, group: int | None = None) -> Any: ...

    def set_sum_commands(self, served: bool) -> Any: ...

    def fail_symbols(self, code: int, symbols: Sequence[str]) -> Any: ...

    def clear_faults(self) -> Any: ...

    def describe(self) -> Any: ...


class ControlError(Exception):
    """A control request that cannot be served, with its HTTP status."""

    def __init__(self, status: HTTPStatus, message: str) -> None:
        super().__init__(message)
        self.status = status


def to_json_value(value: Any) -> Any:
    """JSON-ready form of a process-image value (numpy, bytes, tuples)."""
    if isinstance(value, bytes | bytearray | memoryview):
        return list(bytes(value))
    tolist = getattr(value, "tolist", None)
    if callable(tolist):
        return tolist()
    if isinstance(value, Mapping):
        return {str(k): to_json_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_json_value(v) for v in value]
    return value


@dataclass(frozen=True)
class Endpoints:
    """Where the simulator listens, for the ready line and GET /status."""

    net_id: str
    host: str
    tcp_port: int
    udp_port: int | None
    control_port: int | None


class SimControl:
    """Counters, symbol values and faults of one running simulator.

    Safe to call from any thread: calls from outside the simulator's event
    loop are run inside it and wait for the result.
    """

    def __init__(
        self,
        server: AmsServer,
        target: ControllableTarget,
        loop: asyncio.AbstractEventLoop,
        endpoints: Callable[[], Endpoints],
    ) -> None:
        self._server = server
        self._target = target
        self._loop = loop
        self._endpoints = endpoints
        self._model_faults: list[Fault] = []
        self._loop_thread = threading.get_ident()
        """SimControl is made inside the simulator's loop, on its thread."""

    def _call(self, function: Callable[[], _T]) -> _T:
        if threading.get_ident() == self._loop_thread:
            return function()
        future: concurrent.futures.Future[_T] = concurrent.futures.Future()

        def run() -> None:
            try:
                future.set_result(function())
            except BaseException as error:
                future.set_exception(error)

        self._loop.call_soon_threadsafe(run)
        return future.result(timeout=CALL_TIMEOUT_SECONDS)

    # -- counters ----------------------------------------------------------------

    def counters(self) -> dict[str, Any]:
        """Requests per command ("READ_WRITE") and group ("0xF080"), and more."""
        return self._call(self._server.counters.snapshot)

    def reset_counters(self) -> dict[str, Any]:
        def reset() -> dict[str, Any]:
            self._server.counters.reset()
            return self._server.counters.snapshot()

        return self._call(reset)

    # -- process image -----------------------------------------------------------

    def get_symbol(self, name: str) -> Any:
        """The value of a symbol, by its TwinCAT name."""
        return self._call(lambda: self._target.get_symbol_value(name))

    def set_symbol(self, name: str, value: Any) -> Any:
        """Force a symbol's value; returns the value as now read back."""

        def force() -> Any:
            self._target.set_symbol_value(name, value)
            return self._target.get_symbol_value(name)

        return self._call(force)

    # -- faults ------------------------------------------------------------------

    def add_fault(self, kind: str | FaultKind | Fault, **params: Any) -> Fault:
        """Switch a fault on, e.g. `add_fault("refuse", seconds=2)`."""
        fault = (
            kind if isinstance(kind, Fault) else parse_fault({"kind": kind, **params})
        )
        self._call(lambda: self._apply(fault))
        return fault

    def clear_faults(self) -> None:
        """Every fault off: transport faults, model faults, run state RUN."""

        def clear() -> None:
            self._server.clear_faults()
            self._target.clear_faults()
            self._model_faults.clear()

        self._call(clear)

    def faults(self) -> list[dict[str, Any]]:
        """The faults in force (one-shot faults such as drop are not listed)."""

        def active() -> list[dict[str, Any]]:
            model = [fault.to_json() for fault in self._model_faults]
            return self._server.active_faults() + model

        return self._call(active)

    def _apply(self, fault: Fault) -> None:
        params = fault.params
        match fault.kind:
            case FaultKind.DROP:
                self._server.drop_connections()
            case FaultKind.REFUSE:
                self._server.refuse(params["seconds"])
            case FaultKind.STALL:
                self._server.stall(params.get("seconds"))
            case FaultKind.ERROR if "symbols" in params:
                try:
                    self._target.fail_symbols(params["code"], params["symbols"])
                except KeyError as error:
                    raise FaultError(str(error.args[0])) from None
                self._model_faults.append(fault)
            case FaultKind.ERROR:
                self._server.force_error(params["code"], params.get("group"))
                self._target.force_error(params["code"], params.get("group"))
            case FaultKind.SLAVE_STATE:
                self._target.set_slave_state(
                    _slave(params), params["state"], params.get("device")
                )
                self._model_faults.append(fault)
            case FaultKind.LINK_LOST:
                self._target.set_link_lost(
                    _slave(params), params["lost"], params.get("device")
                )
                self._model_faults.append(fault)
            case FaultKind.ONLINE_CHANGE:
                self._target.online_change(
                    params.get("pdo_groups"), params.get("removed", ())
                )
            case FaultKind.STOP:
                self._target.set_run_state(False)
                self._model_faults.append(fault)
            case FaultKind.NO_SUM_COMMANDS:
                self._target.set_sum_commands(False)
                self._model_faults.append(fault)

    # -- status ------------------------------------------------------------------

    def status(self) -> dict[str, Any]:
        def collect() -> dict[str, Any]:
            endpoints = self._endpoints()
            return {
                "net_id": endpoints.net_id,
                "host": endpoints.host,
                "tcp_port": endpoints.tcp_port,
                "udp_port": endpoints.udp_port,
                "control_port": endpoints.control_port,
                "connections": len(self._server.connections),
                "notifications": self._server.notification_count,
                "faults": self._server.active_faults()
                + [fault.to_json() for fault in self._model_faults],
                "model": to_json_value(self._target.describe()),
            }

        return self._call(collect)


def _slave(params: Mapping[str, Any]) -> int | str | None:
    """The slave a fault names: address, TwinCAT name, or None for all."""
    return params.get("address", params.get("name"))


# -- HTTP ------------------------------------------------------------------------


def _json_body(body: bytes) -> Any:
    if not body:
        raise ControlError(HTTPStatus.BAD_REQUEST, "a JSON body is required")
    try:
        return json.loads(body)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ControlError(
            HTTPStatus.BAD_REQUEST, f"body is not JSON: {error}"
        ) from None


def _symbol_call(function: Callable[[], Any]) -> Any:
    try:
        return function()
    except LookupError as error:
        raise ControlError(HTTPStatus.NOT_FOUND, f"no such symbol: {error}") from None
    except (ValueError, TypeError, OverflowError) as error:
        raise ControlError(HTTPStatus.BAD_REQUEST, str(error)) from None


class ControlRoutes:
    """Maps (method, path, body) to a JSON answer using a `SimControl`."""

    def __init__(self, control: SimControl) -> None:
        self._control = control

    def handle(self, method: str, target: str, body: bytes) -> tuple[HTTPStatus, Any]:
        path = urlsplit(target).path
        control = self._control
        if path == "/counters":
            if method == "GET":
                return HTTPStatus.OK, control.counters()
            if method == "DELETE":
                return HTTPStatus.OK, control.reset_counters()
            return self._not_allowed(method, path)
        if path.startswith("/symbols/") and len(path) > len("/symbols/"):
            name = unquote(path[len("/symbols/") :])
            if method == "GET":
                value = _symbol_call(lambda: control.get_symbol(name))
                return HTTPStatus.OK, {"name": name, "value": to_json_value(value)}
            if method == "PUT":
                request = _json_body(body)
                if not isinstance(request, dict) or "value" not in request:
                    raise ControlError(
                        HTTPStatus.BAD_REQUEST, 'body must be {"value": ...}'
                    )
                value = _symbol_call(lambda: control.set_symbol(name, request["value"]))
                return HTTPStatus.OK, {"name": name, "value": to_json_value(value)}
            return self._not_allowed(method, path)
        if path == "/faults":
            if method == "GET":
                return HTTPStatus.OK, {"active": control.faults()}
            if method == "POST":
                try:
                    fault = control.add_fault(parse_fault(_json_body(body)))
                except FaultError as error:
                    raise ControlError(HTTPStatus.BAD_REQUEST, str(error)) from None
                return HTTPStatus.OK, {
                    "applied": fault.to_json(),
                    "active": control.faults(),
                }
            if method == "DELETE":
                control.clear_faults()
                return HTTPStatus.OK, {"active": control.faults()}
            return self._not_allowed(method, path)
        if path in ("/", "/status"):
            if method == "GET":
                return HTTPStatus.OK, control.status()
            return self._not_allowed(method, path)
        raise ControlError(HTTPStatus.NOT_FOUND, f"no such resource: {path}")

    @staticmethod
    def _not_allowed(method: str, path: str) -> tuple[HTTPStatus, Any]:
        raise ControlError(
            HTTPStatus.METHOD_NOT_ALLOWED, f"{method} not allowed on {path}"
        )


def _http_response(status: HTTPStatus, document: Any) -> bytes:
    body = json.dumps(document, default=str).encode() + b"\n"
    head = (
        f"HTTP/1.1 {status.value} {status.phrase}\r\n"
        "Content-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n"
        "Connection: close\r\n\r\n"
    )
    return head.encode("latin-1") + body


class ControlHttpServer:
    """The HTTP/JSON face of `SimControl` (HTTP/1.1, one request per connection)."""

    def __init__(self, control: SimControl) -> None:
        self._routes = ControlRoutes(control)
        self._server: asyncio.Server | None = None
        self.port = 0

    async def start(self, host: str = LOOPBACK, port: int = 0) -> None:
        self._server = await asyncio.start_server(self._serve, host, port)
        self.port = self._server.sockets[0].getsockname()[1]

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
            self._server = None

    async def _serve(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        try:
            try:
                method, target, body = await asyncio.wait_for(
                    self._read_request(reader), HEADER_TIMEOUT_SECONDS
                )
                status, document = self._routes.handle(method, target, body)
            except ControlError as error:
                status, document = error.status, {"error": str(error)}
            except (TimeoutError, asyncio.IncompleteReadError, ValueError) as error:
                status, document = (
                    HTTPStatus.BAD_REQUEST,
                    {"error": f"bad request: {error}"},
                )
            except Exception as error:
                log.exception("control request failed")
                status = HTTPStatus.INTERNAL_SERVER_ERROR
                document = {"error": f"{type(error).__name__}: {error}"}
            writer.write(_http_response(status, document))
            await writer.drain()
        except (ConnectionError, OSError):
            pass
        finally:
            writer.close()

    @staticmethod
    async def _read_request(reader: asyncio.StreamReader) -> tuple[str, str, bytes]:
        request_line = (await reader.readline()).decode("latin-1").split()
        if len(request_line) != 3 or not request_line[2].startswith("HTTP/"):
            raise ControlError(HTTPStatus.BAD_REQUEST, "malformed request line")
        method, target, _ = request_line
        length = 0
        while True:
            line = await reader.readline()
            if line in (b"\r\n", b"\n", b""):
                break
            name, _, value = line.decode("latin-1").partition(":")
            if name.strip().lower() == "content-length":
                length = int(value.strip())
        if not 0 <= length <= MAX_BODY_SIZE:
            raise ControlError(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, "body too large")
        body = await reader.readexactly(length) if length else b""
        return method.upper(), target, body
