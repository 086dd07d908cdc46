"""`fastcs_ethercat.process`: a child's held stdin, free ports on a host."""

from __future__ import annotations

import socket
import sys

import pytest

from fastcs_ethercat.process import ChildProcess, free_port
from tests.processes import wait_for_line

ECHO_UPPER = "import sys\nfor line in sys.stdin:\n    print(line.upper(), end='')"


@pytest.mark.e2e
def test_a_held_stdin_reaches_the_child_and_its_end_ends_the_child() -> None:
    child = ChildProcess(
        [sys.executable, "-u", "-c", ECHO_UPPER], "echo", stdin_pipe=True
    )
    with child:
        child.launch()
        assert child.stdin is not None
        child.stdin.write("hello\n")
        child.stdin.flush()
        answer = wait_for_line(child, "HELLO", 30)
        child.stdin.close()  # EOF, as `stop` sends it first
        code = child.wait(30)

    assert answer == "HELLO"
    assert code == 0


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost"])
def test_a_free_port_of_the_host_asked_for_takes_a_server(host: str) -> None:
    port = free_port(tcp=True, udp=False, host=host)

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.bind((host, port))
        server.listen()
        bound = server.getsockname()

    assert bound == ("127.0.0.1", port)
