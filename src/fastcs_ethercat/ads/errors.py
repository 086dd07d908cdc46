"""The exceptions of the ADS layer: one for bytes the codec refuses, and the
`AdsError` family a client raises, typed by what went wrong.

Callers branch on the type, never on the message: a timeout, a target that
cannot be reached (and why: refused, unreachable, unknown host), a symbol or
handle that an online change invalidated, a peer that broke the protocol.
"""

from __future__ import annotations

from typing import Final

from fastcs_ethercat.ads.constants import AdsReturnCode, describe_return_code


class AdsCodecError(ValueError):
    """Bytes that break the ADS layout, with the return code a server answers.

    A server turns `return_code` into the `result` of its response (or the AMS
    error code); a client treats it as a protocol violation of its peer.
    """

    def __init__(
        self,
        message: str,
        return_code: AdsReturnCode = AdsReturnCode.DEVICE_INVALID_SIZE,
    ) -> None:
        super().__init__(message)
        self.return_code = return_code


class AdsError(Exception):
    """An ADS request failed; `code` is the ADS return code."""

    def __init__(
        self,
        code: int,
        operation: str,
        target: str,
        detail: str = "",
        *,
        message: str | None = None,
    ) -> None:
        self.code = code
        self.operation = operation
        self.target = target
        if message is None:
            message = f"{operation} on {target} failed: {describe_return_code(code)}"
            if detail:
                message = f"{message}: {detail}"
        super().__init__(message)


class AdsTimeoutError(AdsError):
    """No answer in time (0x745 from the client, 0x719 from a device)."""


class AdsConnectionError(AdsError):
    """The target cannot be reached: socket, AMS routing or port errors."""


class AdsConnectionRefusedError(AdsConnectionError):
    """Nothing listens on the target's ADS port (TCP connection refused)."""


class AdsHostUnreachableError(AdsConnectionError):
    """No route to the target host (network or host unreachable)."""


class AdsUnknownHostError(AdsConnectionError):
    """The target's host name does not resolve."""


class AdsConnectTimeoutError(AdsConnectionError, AdsTimeoutError):
    """The TCP connection to the target was not established in time."""


class AdsConnectionLostError(AdsConnectionError):
    """The connection closed or broke while the request waited for its answer."""


class AdsSymbolError(AdsError):
    """A symbol is gone or changed (0x710, 0x711, 0x722): resolve it again."""


class AdsHandleInvalidError(AdsSymbolError):
    """A symbol handle no longer holds (unknown 0x710, or taken before an
    online change 0x711): acquire it again by name."""


class AdsProtocolError(AdsError):
    """The target answered with bytes that break the ADS layout."""


class AdsRouteError(AdsError):
    """The target refused to add our route (wrong user or password)."""


SOCKET_ERRORS: Final = frozenset(
    {
        AdsReturnCode.SOCKET_CONNECTION_TIMEOUT,
        AdsReturnCode.SOCKET_CONNECTION_REFUSED,
        AdsReturnCode.SOCKET_HOST_UNREACHABLE,
        AdsReturnCode.SOCKET_HOST_NOT_FOUND,
        AdsReturnCode.SOCKET_CONNECTION_RESET,
    }
)
"""Codes of the socket errors (Winsock numbers, as TwinCAT's clients report
them) behind the connection errors above."""
_TIMEOUTS: Final = frozenset(
    {
        AdsReturnCode.CLIENT_SYNC_TIMEOUT,
        AdsReturnCode.DEVICE_TIMEOUT,
        AdsReturnCode.AMS_SYNC_TIMEOUT,
    }
)
HANDLE_ERRORS: Final = frozenset(
    {
        AdsReturnCode.DEVICE_SYMBOL_NOT_FOUND,
        AdsReturnCode.DEVICE_SYMBOL_VERSION_INVALID,
    }
)
"""What a request by handle answers when the handle is unknown or outdated."""
_SYMBOL_ERRORS: Final = HANDLE_ERRORS | {AdsReturnCode.DEVICE_SYMBOL_NOT_ACTIVE}
_NO_ANSWER: Final = frozenset(
    {
        AdsReturnCode.CLIENT_PORT_NOT_OPEN,
        AdsReturnCode.CLIENT_NO_AMS_ADDR,
        AdsReturnCode.CLIENT_SYNC_RES_INVALID,  # garbage is no answer either
    }
)


def unreachable(code: int) -> bool:
    """The code says the target did not answer (timeout, socket, routing or
    port, or a malformed answer), rather than that it answered with an error."""
    if code in _TIMEOUTS or code in SOCKET_ERRORS or code in _NO_ANSWER:
        return True
    return code < AdsReturnCode.DEVICE_ERROR and code not in _SYMBOL_ERRORS


def ads_error(
    code: int, operation: str, target: str, detail: str = "", *, by_handle: bool = False
) -> AdsError:
    """The typed exception for an ADS return code (`by_handle`: the request
    addressed a symbol handle, so 0x710 / 0x711 mean the handle is invalid)."""
    kind: type[AdsError] = AdsError
    if code in _TIMEOUTS:
        kind = AdsTimeoutError
    elif by_handle and code in HANDLE_ERRORS:
        kind = AdsHandleInvalidError
    elif code in _SYMBOL_ERRORS:
        kind = AdsSymbolError
    elif unreachable(code):
        kind = AdsConnectionError
    return kind(code, operation, target, detail)
