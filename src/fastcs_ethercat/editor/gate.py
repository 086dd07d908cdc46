"""Who may use the editor: anyone on this machine when it binds loopback;
off loopback, only who holds its token.

The editor writes terminal files, so on any other address (`--host`) every
request (pages, files, the socket.io channel) must carry the token, in the
URL once (`?token=...`, printed at start) and then in a cookie the first
answer sets. The token is `FASTCS_ETHERCAT_EDITOR_TOKEN` when set, else a
new random one each start. There is no TLS: on an untrusted network put the
editor behind a proxy that adds it, or keep it on loopback and tunnel.
"""

from __future__ import annotations

import ipaddress
import logging
import secrets
from collections.abc import Awaitable, Callable, Mapping, MutableMapping
from http.cookies import SimpleCookie
from typing import Any, Final
from urllib.parse import parse_qs

log = logging.getLogger(__name__)

TOKEN_ENV: Final = "FASTCS_ETHERCAT_EDITOR_TOKEN"
COOKIE: Final = "fastcs_ethercat_editor"
MIN_TOKEN_CHARS: Final = 16

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
Asgi = Callable[[Scope, Receive, Send], Awaitable[None]]


def is_loopback(host: str) -> bool:
    """127.0.0.0/8, ::1 or `localhost`; a name or any other address is not."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def editor_token(host: str, environ: Mapping[str, str]) -> str | None:
    """The token the editor on `host` requires (None on loopback), warning
    once that it serves beyond this machine."""
    if is_loopback(host):
        return None
    token = environ.get(TOKEN_ENV) or secrets.token_urlsafe(24)
    if len(token) < MIN_TOKEN_CHARS:
        from fastcs_ethercat.errors import UserError

        raise UserError(f"{TOKEN_ENV} must hold at least {MIN_TOKEN_CHARS} characters")
    log.warning(
        "the editor serves on %s, beyond this machine: whoever has the token "
        "may change the terminal files; no TLS (keep it on a trusted network)",
        host,
    )
    return token


class TokenGate:
    """ASGI middleware: a request passes with the token in its query or its
    cookie; else 401 (HTTP) or a refused socket (WebSocket)."""

    def __init__(self, app: Asgi, token: str) -> None:
        self.app = app
        self.token = token

    def _given(self, scope: Scope) -> tuple[bool, bool]:
        """(allowed, token in the query)."""
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        in_query = any(self._same(value) for value in query.get("token", []))
        cookie = SimpleCookie()
        for name, value in scope.get("headers", []):
            if name == b"cookie":
                cookie.load(value.decode("latin-1"))
        morsel = cookie.get(COOKIE)
        in_cookie = morsel is not None and self._same(morsel.value)
        return in_query or in_cookie, in_query

    def _same(self, value: str) -> bool:
        return secrets.compare_digest(value.encode(), self.token.encode())

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        allowed, in_query = self._given(scope)
        if not allowed:
            await _refuse(scope, send)
            return
        if in_query and scope["type"] == "http":
            send = self._setting_cookie(send)
        await self.app(scope, receive, send)

    def _setting_cookie(self, send: Send) -> Send:
        value = f"{COOKIE}={self.token}; Path=/; HttpOnly; SameSite=Strict"

        async def sending(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                headers.append((b"set-cookie", value.encode("latin-1")))
                message["headers"] = headers
            await send(message)

        return sending


async def _refuse(scope: Scope, send: Send) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008})
        return
    body = b"the editor needs its token: open the URL it printed at start\n"
    await send(
        {
            "type": "http.response.start",
            "status": 401,
            "headers": [(b"content-type", b"text/plain; charset=utf-8")],
        }
    )
    await send({"type": "http.response.body", "body": body})
