"""The control API over HTTP (and SimControl across threads)."""

from __future__ import annotations

import json
import socket
import struct
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any
from urllib.parse import quote

import pytest

from fastcs_ethercat.sim.runner import SimulatorConfig
from tests.sim_support import StandInTarget
from tests.sim_thread import SimulatorThread


@pytest.fixture(scope="module")
def sim() -> Iterator[SimulatorThread]:
    config = SimulatorConfig(port=0, udp_port=None, control_port=0)
    with SimulatorThread(StandInTarget(), config) as sim:
        yield sim


def call(
    sim: SimulatorThread, method: str, path: str, body: Any = None
) -> tuple[int, Any]:
    port = sim.endpoints.control_port
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}", data=data, method=method
    )
    try:
        with urllib.request.urlopen(request, timeout=10) as answer:
            return answer.status, json.loads(answer.read())
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read())


def raw_http(sim: SimulatorThread, data: bytes) -> bytes:
    port = sim.endpoints.control_port
    assert port is not None
    with socket.create_connection(("127.0.0.1", port), timeout=10) as connection:
        connection.sendall(data)
        connection.shutdown(socket.SHUT_WR)
        chunks = []
        while chunk := connection.recv(65536):
            chunks.append(chunk)
    return b"".join(chunks)


def test_counters_are_json_and_resettable(sim: SimulatorThread) -> None:
    status, counters = call(sim, "GET", "/counters")
    assert status == 200
    assert {"total", "commands", "index_groups"} <= set(counters)
    status, counters = call(sim, "DELETE", "/counters")
    assert status == 200
    assert counters["total"] == 0


def test_symbol_read_and_force(sim: SimulatorThread) -> None:
    status, body = call(sim, "PUT", "/symbols/Value", {"value": 123456})
    assert (status, body) == (200, {"name": "Value", "value": 123456})
    assert call(sim, "GET", "/symbols/Value") == (200, body)
    target = sim.simulator.target
    assert isinstance(target, StandInTarget)
    assert struct.unpack_from("<I", target.inputs, 4)[0] == 123456


def test_symbol_names_are_url_decoded(sim: SimulatorThread) -> None:
    status, body = call(sim, "GET", "/symbols/" + quote("Term 1 (EK1100).ID"))
    assert status == 404
    assert "Term 1 (EK1100).ID" in body["error"]


@pytest.mark.parametrize(
    ("method", "path", "body", "status"),
    [
        ("GET", "/symbols/Nope", None, 404),
        ("PUT", "/symbols/Value", {"value": "text"}, 400),
        ("PUT", "/symbols/Flag", {"value": 300}, 400),
        ("PUT", "/symbols/Value", {"wrong": 1}, 400),
        ("POST", "/faults", {"kind": "melt"}, 400),
        ("POST", "/faults", {"kind": "refuse"}, 400),
        ("PATCH", "/faults", {}, 405),
        ("POST", "/counters", {}, 405),
        ("GET", "/nowhere", None, 404),
    ],
)
def test_bad_requests_get_an_error_document(
    sim: SimulatorThread, method: str, path: str, body: Any, status: int
) -> None:
    got, document = call(sim, method, path, body)
    assert got == status
    assert isinstance(document["error"], str)


def test_faults_post_list_and_delete(sim: SimulatorThread) -> None:
    status, body = call(sim, "POST", "/faults", {"kind": "error", "code": 1793})
    assert status == 200
    assert body["applied"] == {"kind": "error", "code": 1793}
    assert call(sim, "GET", "/faults")[1]["active"] == [
        {"kind": "error", "code": 1793, "group": None}
    ]
    status, body = call(
        sim, "POST", "/faults", {"kind": "slave_state", "state": "INIT"}
    )
    assert status == 200
    assert len(body["active"]) == 2
    assert call(sim, "DELETE", "/faults") == (200, {"active": []})


def test_the_fault_no_sum_commands_reaches_the_target(sim: SimulatorThread) -> None:
    target = sim.simulator.target
    assert isinstance(target, StandInTarget)
    status, body = call(sim, "POST", "/faults", {"kind": "no_sum_commands"})
    assert status == 200
    assert body["active"] == [{"kind": "no_sum_commands"}]
    assert ("set_sum_commands", (False,)) in target.calls
    assert call(sim, "POST", "/faults", {"kind": "no_sum_commands", "x": 1})[0] == 400
    assert call(sim, "DELETE", "/faults") == (200, {"active": []})


def test_status_names_the_endpoints(sim: SimulatorThread) -> None:
    status, body = call(sim, "GET", "/status")
    assert status == 200
    assert body["net_id"] == "10.20.30.40.1.1"
    assert body["tcp_port"] == sim.endpoints.tcp_port
    assert body["control_port"] == sim.endpoints.control_port
    assert body["model"] == {"stand_in": True, "symbols": ["Counter", "Flag", "Value"]}


def test_malformed_http_gets_400_and_the_server_lives(sim: SimulatorThread) -> None:
    assert raw_http(sim, b"garbage\r\n\r\n").startswith(b"HTTP/1.1 400")
    big = b"POST /faults HTTP/1.1\r\nContent-Length: 99999999\r\n\r\n"
    assert raw_http(sim, big).startswith(b"HTTP/1.1 413")
    not_json = b"POST /faults HTTP/1.1\r\nContent-Length: 3\r\n\r\n{{{"
    assert raw_http(sim, not_json).startswith(b"HTTP/1.1 400")
    assert raw_http(sim, b"").startswith(b"HTTP/1.1 400")
    assert call(sim, "GET", "/counters")[0] == 200


def test_python_api_works_from_another_thread(sim: SimulatorThread) -> None:
    control = sim.control
    control.set_symbol("Flag", 1)
    assert control.get_symbol("Flag") == 1
    control.add_fault("stop")
    assert control.faults() == [{"kind": "stop"}]
    control.clear_faults()
    assert control.faults() == []
    with pytest.raises(KeyError):
        control.get_symbol("Nope")
