"""The client side of the robot's control channel (`atemr.io.control_socket`): connect, ask, read answers.

Every failure to reach the robot is a `ControlError` that says what to do: no socket means no robot is
running (start one with ``./run``, or run the mission in a fresh simulation with ``--headless``); a socket
nobody answers on was left by a robot that stopped without cleaning up; permission denied means the robot
runs as another user, and only that user may control it.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

from atemr.errors import ControlError
from atemr.io.control_socket import MAX_LINE_BYTES

#: What to do when no robot answers (the CLI adds it to the error).
HOW_TO_START = "start the robot with ./run (or atemr run), or add --headless to run in a fresh simulation"


class ControlClient:
    """One connection to a running robot's control socket (a context manager)."""

    def __init__(self, path: Path, *, timeout_s: float | None = 20.0) -> None:
        self.path = Path(path)
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.settimeout(timeout_s)
        try:
            self.sock.connect(str(self.path))
        except FileNotFoundError:
            self.sock.close()
            raise ControlError(f"no robot is running: there is no control socket at {self.path}; "
                               f"{HOW_TO_START}") from None
        except ConnectionRefusedError:
            self.sock.close()
            raise ControlError(f"no robot is running: nothing answers on {self.path} (left by a robot that "
                               f"stopped without cleaning up); {HOW_TO_START}") from None
        except PermissionError:
            self.sock.close()
            raise ControlError(f"permission denied on {self.path}: the robot runs as another user, and only "
                               f"that user may control it") from None
        except OSError as exc:
            self.sock.close()
            raise ControlError(f"cannot connect to the robot at {self.path}: {exc.strerror or exc}") from None
        self._lines = self.sock.makefile("rb")

    def send(self, request: Mapping[str, Any]) -> None:
        """Write one request line."""
        try:
            self.sock.sendall((json.dumps(request, allow_nan=False) + "\n").encode("utf-8"))
        except OSError as exc:
            raise ControlError(f"lost the connection to the robot ({exc.strerror or exc})") from None

    def receive(self) -> dict[str, Any]:
        """Read one answer (blocks up to the connection's timeout)."""
        try:
            line = self._lines.readline(MAX_LINE_BYTES + 1)
        except TimeoutError:
            raise ControlError("the robot did not answer in time (is its control loop running?)") from None
        except OSError as exc:
            raise ControlError(f"lost the connection to the robot ({exc.strerror or exc})") from None
        if not line:
            raise ControlError("the robot closed the connection (did it stop?)")
        try:
            answer = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ControlError(f"the robot sent something that is not JSON: {exc.msg}") from None
        if not isinstance(answer, dict):
            raise ControlError(f"the robot sent a {type(answer).__name__}, expected a JSON object")
        return answer

    def request(self, request: Mapping[str, Any]) -> dict[str, Any]:
        """Send one request and return its answer; a refusal raises `ControlError` with the robot's reason."""
        self.send(request)
        return checked(self.receive())

    def answers(self) -> Iterator[dict[str, Any]]:
        """Every following answer, as it comes (refusals raise)."""
        while True:
            yield checked(self.receive())

    def set_timeout(self, timeout_s: float | None) -> None:
        self.sock.settimeout(timeout_s)

    def close(self) -> None:
        self._lines.close()
        self.sock.close()

    def __enter__(self) -> ControlClient:
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.close()


def checked(answer: dict[str, Any]) -> dict[str, Any]:
    """``answer`` if the robot said ok; else `ControlError` with its reason."""
    if answer.get("ok") is not True:
        raise ControlError(f"the robot refused: {answer.get('error') or answer}")
    return answer


__all__ = ["HOW_TO_START", "ControlClient", "checked"]
