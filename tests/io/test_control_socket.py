"""The control socket's framing and life: refusals on the wire, private permissions, stale and live sockets."""

from __future__ import annotations

import os
import socket
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from atemr.errors import ConfigError, ControlError
from atemr.io.control_client import ControlClient
from atemr.io.control_socket import MAX_LINE_BYTES, ControlConnection, ControlServer


def echo(request: dict[str, Any], conn: ControlConnection) -> None:
    conn.send({"ok": True, "echo": request.get("text")})


def broken(request: dict[str, Any], conn: ControlConnection) -> None:
    raise RuntimeError("a bug")


def refused(request: dict[str, Any], conn: ControlConnection) -> None:
    raise ControlError("not now")


@pytest.fixture
def server(tmp_path: Path) -> Iterator[ControlServer]:
    server = ControlServer(tmp_path / "control.sock", {"echo": echo, "broken": broken, "refused": refused})
    server.start()
    yield server
    server.stop()


def raw(client: ControlClient, line: bytes) -> dict[str, Any]:
    client.sock.sendall(line)
    return client.receive()


def test_bad_requests_are_refused_with_the_reason_and_the_connection_stays_usable(server: ControlServer) -> None:
    with ControlClient(server.path, timeout_s=10) as client:
        bad = raw(client, b'{"cmd": "echo", \n')
        assert bad == {"ok": False, "error": "bad JSON at line 1 column 17: Expecting property name enclosed in "
                                             "double quotes"}
        assert raw(client, b"[1, 2]\n")["error"].startswith("a request is a JSON object")
        assert raw(client, b'{"text": "no command"}\n')["error"] == 'a request needs "cmd" (one of broken, echo, ' \
                                                                       'refused)'
        unknown = raw(client, b'{"cmd": "ecoh"}\n')
        assert unknown["error"] == "unknown command 'ecoh' (did you mean 'echo'?); commands: broken, echo, refused"
        assert raw(client, b"\xff\xfe\n")["error"].startswith("bad request: not UTF-8")
        assert raw(client, b'{"cmd": "refused"}\n') == {"ok": False, "error": "not now"}
        assert raw(client, b'{"cmd": "broken"}\n')["error"] == "internal error in 'broken': RuntimeError: a bug"
        assert client.request({"cmd": "echo", "text": "still here"}) == {"ok": True, "echo": "still here"}


def test_a_refusal_raises_on_the_client_with_the_robots_reason(server: ControlServer) -> None:
    with ControlClient(server.path) as client, pytest.raises(ControlError, match="the robot refused: not now"):
        client.request({"cmd": "refused"})


def test_an_overlong_request_is_refused_and_the_connection_closed(server: ControlServer) -> None:
    with ControlClient(server.path) as client:
        answer = raw(client, b"x" * (MAX_LINE_BYTES + 10) + b"\n")
        assert answer["error"] == f"request longer than {MAX_LINE_BYTES} bytes; connection closed"
        with pytest.raises(ControlError, match="closed the connection"):
            client.receive()


def test_the_socket_is_private_and_removed_on_a_clean_stop(tmp_path: Path) -> None:
    server = ControlServer(tmp_path / "run" / "control.sock", {"echo": echo})
    server.start()
    mode = os.stat(server.path).st_mode
    assert stat.S_ISSOCK(mode) and stat.S_IMODE(mode) == 0o600
    assert sorted(p.name for p in server.path.parent.iterdir()) == ["control.sock"]  # no temporary left behind
    server.stop()
    assert not server.path.exists()
    server.stop()  # idempotent


def stale_socket(path: Path) -> None:
    """What a crashed robot leaves: a socket file nobody listens on."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(path))
    sock.close()


def test_a_stale_socket_is_detected_and_replaced(tmp_path: Path) -> None:
    path = tmp_path / "control.sock"
    stale_socket(path)
    with pytest.raises(ControlError, match=r"no robot is running: nothing answers on .*left by a robot that stopped"):
        ControlClient(path)
    server = ControlServer(path, {"echo": echo})
    server.start()
    try:
        with ControlClient(path) as client:
            assert client.request({"cmd": "echo", "text": "new"})["echo"] == "new"
    finally:
        server.stop()
    assert not path.exists()


def test_a_live_socket_is_not_taken_over(server: ControlServer) -> None:
    second = ControlServer(server.path, {"echo": echo})
    with pytest.raises(ControlError, match="another robot is already running with the control socket"):
        second.start()
    with ControlClient(server.path) as client:
        assert client.request({"cmd": "echo", "text": "first"})["echo"] == "first"


def test_a_file_that_is_not_a_socket_is_left_alone(tmp_path: Path) -> None:
    path = tmp_path / "control.sock"
    path.write_text("notes")
    with pytest.raises(ControlError, match="exists and is not a socket: refusing to replace it"):
        ControlServer(path, {"echo": echo}).start()
    assert path.read_text() == "notes"


def test_no_socket_says_no_robot_runs_and_how_to_start_one(tmp_path: Path) -> None:
    with pytest.raises(ControlError) as error:
        ControlClient(tmp_path / "control.sock")
    assert "no robot is running" in str(error.value) and "./run" in str(error.value)
    assert "--headless" in str(error.value)


def test_a_path_too_long_for_a_unix_socket_is_a_config_error(tmp_path: Path) -> None:
    path = tmp_path / ("d" * 60) / ("e" * 60) / "control.sock"
    with pytest.raises(ConfigError, match="more than the 107 a Unix socket allows"):
        ControlServer(path, {"echo": echo}).start()
