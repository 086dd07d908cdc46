"""Graylog through FastCS's own options: an IOC started with
`--graylog-endpoint` sends its log lines (ours and FastCS's) as GELF to a UDP
socket on loopback, with the static fields asked for."""

from __future__ import annotations

import json
import socket
import time
import zlib
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT
from tests.ioc_support import (
    IOC_COMMAND,
    ioc_env,
    new_token,
    start_ioc,
    write_ioc_config,
)

DEMO_CHAIN = REPO_ROOT / "ioc" / "demo-chain.yaml"


def _messages(sock: socket.socket, until: float) -> list[dict[str, object]]:
    found: list[dict[str, object]] = []
    while time.monotonic() < until:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            continue
        found.append(json.loads(zlib.decompress(data)))
        if any("serving" in str(m.get("short_message")) for m in found):
            break
    return found


@pytest.mark.e2e
def test_log_lines_reach_a_graylog_input(tmp_path: Path) -> None:
    token = new_token()
    env = ioc_env(token)
    prefix = f"GRL{token[:6].upper()}"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(0.5)
        port = sock.getsockname()[1]
        config = write_ioc_config(
            tmp_path, prefix, "127.0.0.1:1", "127.0.0.1.1.1", chain=str(DEMO_CHAIN)
        )
        ioc = start_ioc(
            [
                *IOC_COMMAND,
                "--config",
                str(config),
                "--graylog-endpoint",
                f"127.0.0.1:{port}",
                "--graylog-static-fields",
                "beamline:BL01T",
            ],
            prefix,
            env,
            token,
        )
        try:
            messages = _messages(sock, time.monotonic() + 60)
        finally:
            ioc.stop()

    texts = [str(m.get("short_message")) for m in messages]
    assert any("serving" in t for t in texts), texts
    assert all(m.get("beamline") == "BL01T" for m in messages)  # static field
    assert any(
        str(m.get("_logger_name", "")).startswith("fastcs_ethercat") for m in messages
    )
