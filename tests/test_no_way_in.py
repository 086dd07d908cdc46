"""No way in: names from outside never become paths outside their directory;
the editor off loopback wants its token; an ACF that leaves our groups to
DEFAULT is said so at start."""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from fastcs_ethercat.editor.gate import COOKIE, TOKEN_ENV, TokenGate, editor_token
from fastcs_ethercat.editor.session import EditorSession
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.esi import build_catalog
from fastcs_ethercat.ioc.access import groups_left_to_default
from fastcs_ethercat.safe_names import file_in
from fastcs_ethercat.terminals.files import terminal_file_name
from tests.test_input_bounds import esi_with

HOSTILE = ["../../x", "/abs/x", "a/b", "a\\b", "x\0y", "..", ".hidden", ""]


@pytest.mark.parametrize("name", HOSTILE)
def test_a_hostile_type_name_is_not_a_file_name(name: str) -> None:
    with pytest.raises(UserError, match="not a terminal type name"):
        terminal_file_name(name)


@pytest.mark.parametrize("name", ["../x.yaml", "/abs/x.yaml", "a/b.yaml", "..", ""])
def test_a_path_stays_in_its_directory(tmp_path: Path, name: str) -> None:
    with pytest.raises(UserError, match="outside"):
        file_in(tmp_path, name)


def hostile_esi(tmp_path: Path, name: str) -> Path:
    path = esi_with(tmp_path)
    path.write_text(path.read_text().replace(">EL1084</Type>", f">{name}</Type>"))
    return path


@pytest.mark.parametrize("name", ["../../x", "/abs/x"])
def test_an_esi_type_that_is_a_path_is_refused(tmp_path: Path, name: str) -> None:
    catalog = build_catalog(hostile_esi(tmp_path, name), use_cache=False)
    assert len(catalog) == 0
    (warning,) = catalog.warnings
    assert f"<Type> {name!r} is not a terminal type name" in warning


class _HostileCatalog:
    """A catalog whose device is named like a path (as if the ESI check
    were not there): the editor must still refuse to write it."""

    def __init__(self, name: str) -> None:
        self.name = name

    def find(self, type_name: str) -> Any:
        return SimpleNamespace(type_name=self.name, revision=1)

    def load(self, *args: object) -> Any:
        raise AssertionError("never read: the name is refused first")


@pytest.mark.parametrize("name", ["../../x", "/abs/x", "../outside"])
def test_the_editor_refuses_to_write_outside_its_directory(
    tmp_path: Path, name: str
) -> None:
    folder = tmp_path / "a" / "b" / "terminals"
    folder.mkdir(parents=True)
    session = EditorSession(folder, [hostile_esi(tmp_path, name)])
    with pytest.raises(UserError):
        session.add_type(name)  # the ESI check: no such type
    session._catalog = _HostileCatalog(name)  # type: ignore[assignment]
    with pytest.raises(UserError, match="not a terminal type name"):
        session.add_type("EL1084")
    written = [p for p in tmp_path.rglob("*.yaml")]
    assert written == [] and not Path("/abs/x.yaml").exists()


def test_the_editor_wants_no_token_on_loopback() -> None:
    for host in ("127.0.0.1", "::1", "localhost"):
        assert editor_token(host, {}) is None


def test_off_loopback_the_editor_wants_a_token_and_warns(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with caplog.at_level(logging.WARNING):
        made = editor_token("0.0.0.0", {})
    assert made is not None and len(made) >= 16
    assert "beyond this machine" in caplog.text
    assert editor_token("192.0.2.1", {TOKEN_ENV: "s" * 20}) == "s" * 20
    assert editor_token("0.0.0.0", {}) != made  # a new one each start
    with pytest.raises(UserError, match="at least 16"):
        editor_token("0.0.0.0", {TOKEN_ENV: "short"})


def _call(gate: TokenGate, kind: str, query: bytes, cookie: str | None) -> list[Any]:
    headers = [(b"cookie", cookie.encode())] if cookie else []
    scope = {"type": kind, "query_string": query, "headers": headers, "path": "/"}
    sent: list[Any] = []

    async def app(scope: Any, receive: Any, send: Any) -> None:
        await send({"type": "http.response.start", "status": 200, "headers": []})

    async def receive() -> Any:
        return {}

    async def send(message: Any) -> None:
        sent.append(message)

    asyncio.run(TokenGate(app, gate.token)(scope, receive, send))
    return sent


def test_the_gate_lets_the_token_in_and_keeps_others_out() -> None:
    gate = TokenGate(lambda *a: None, "t" * 24)  # type: ignore[arg-type]
    refused = _call(gate, "http", b"", None)
    assert refused[0]["status"] == 401
    assert _call(gate, "http", b"token=wrong", None)[0]["status"] == 401
    assert _call(gate, "websocket", b"", None) == [
        {"type": "websocket.close", "code": 1008}
    ]
    first = _call(gate, "http", b"token=" + b"t" * 24, None)[0]
    assert first["status"] == 200
    assert (b"set-cookie", f"{COOKIE}={'t' * 24}".encode()) in [
        (name, value.split(b";")[0]) for name, value in first["headers"]
    ]
    later = _call(gate, "websocket", b"", f"{COOKIE}={'t' * 24}")
    assert later[0]["status"] == 200


@pytest.mark.parametrize(
    ("text", "left"),
    [
        ("ASG(DEFAULT) {\n RULE(1, READ)\n}\n", ["outputs", "CoE parameters"]),
        ("ASG(DEFAULT) {RULE(1,READ)}\nASG( OUTPUTS ) {RULE(1,READ)}\n", ["CoE"]),
        ("# ASG(OUTPUTS)\nASG(COE) {RULE(1,READ)}\n", ["outputs"]),
        ("ASG(OUTPUTS) {RULE(1,READ)}\nASG(COE) {RULE(1,READ)}\n", []),
    ],
)
def test_an_acf_leaving_our_groups_to_default_is_named(
    text: str, left: list[str]
) -> None:
    found = groups_left_to_default(text)
    assert len(found) == len(left)
    for shown, wanted in zip(found, left, strict=True):
        assert shown.startswith(wanted)


@pytest.mark.e2e
def test_the_ioc_warns_at_start_of_an_acf_leaving_outputs_to_default(
    tmp_path: Path,
) -> None:
    from tests.conftest import REPO_ROOT
    from tests.test_input_bounds import run_cli_measured

    acf = tmp_path / "site.acf"
    acf.write_text("ASG(DEFAULT) {\n    RULE(1, READ)\n    RULE(1, WRITE)\n}\n")
    args = ["ioc", "--config", str(REPO_ROOT / "ioc" / "demo.yaml"), "--list-pvs"]
    chain = ["--chain", str(REPO_ROOT / "ioc" / "demo-chain.yaml")]

    measured = run_cli_measured(*args, *chain, "--acf", str(acf))
    quiet = run_cli_measured(
        *args, *chain, "--acf", str(REPO_ROOT / "ioc" / "access-example.acf")
    )

    assert measured.rc == 0, measured.stderr
    assert "no rules for outputs (ASG OUTPUTS)" in measured.stderr
    assert "no rules for CoE parameters (ASG COE)" in measured.stderr
    assert quiet.rc == 0 and "no rules for" not in quiet.stderr
