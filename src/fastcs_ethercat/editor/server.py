"""`fastcs-ethercat terminals edit`: serve the editor on one address.

Binds 127.0.0.1 unless told otherwise and prints one ready line with its URL
once the server listens; on another address every request needs a token (in
that URL, see `gate`). With `--target` the live terminals are read once at
start (the same discovery as the IOC's).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.process import free_port

READY = "fastcs-ethercat terminals edit ready: url={url}"


def run_editor(
    directory: Path,
    esi: Sequence[Path] | None,
    target: str | None,
    host: str,
    port: int,
    ams_net_id: str | None = None,
) -> None:
    """Serve the editor until interrupted."""
    try:
        from nicegui import app, ui
    except ImportError:
        raise UserError(
            "the editor needs its extra: pip install 'fastcs-ethercat[editor]'"
        ) from None
    from fastcs_ethercat.editor.live import LiveTerminal, read_live_terminals
    from fastcs_ethercat.editor.pages import index_page, type_page
    from fastcs_ethercat.editor.session import EditorSession

    if not directory.is_dir():
        raise UserError("no such directory", path=directory)
    session = EditorSession(directory, esi)
    live: Callable[[], list[LiveTerminal]] | None = None
    if target is not None:
        try:
            found: list[LiveTerminal] | UserError = read_live_terminals(
                target, directory, ams_net_id
            )
        except UserError as error:
            found = error

        def read_once() -> list[LiveTerminal]:
            if isinstance(found, UserError):
                raise found
            return found

        live = read_once

    from fastcs_ethercat.editor.gate import TokenGate, editor_token

    token = editor_token(host, os.environ)
    port = port or free_port(tcp=True, udp=False, host=host)
    url = f"http://{host}:{port}/" + (f"?token={token}" if token else "")
    if token is not None:
        app.add_middleware(TokenGate, token=token)

    @ui.page("/")
    def _index() -> None:
        index_page(session)

    @ui.page("/type/{name}")
    def _type(name: str) -> None:
        type_page(session, name, live)

    app.on_startup(lambda: print(READY.format(url=url), flush=True))
    ui.run(
        host=host,
        port=port,
        title="fastcs-ethercat terminals",
        reload=False,
        show=False,
        show_welcome_message=False,
        uvicorn_logging_level="warning",
        favicon="🔧",
    )
    sys.stdout.flush()
