"""The robot's local control channel: a Unix domain socket speaking line-delimited JSON.

A running robot (``./run``) serves it so that another terminal of the same user can run a mission on it
(``atemr mission run FILE``), follow it, cancel it and read the agent's status. The socket lives in the data
directory (``control.socket`` in the configuration, default ``data_dir/control.sock``) with mode 0600, so
only the OS user that runs the robot can connect: that is the channel's whole access control (no password,
no network). It is bound under a private temporary name and renamed into place, so it is never reachable
with looser permissions, not even for an instant.

A socket left behind by a robot that crashed is detected (nothing answers on it) and replaced; one that
answers belongs to a robot that is still running, and this one refuses to start rather than steal it. A
clean stop removes the socket (only if it is still this robot's).

The protocol: every request is one JSON object on one line, ``{"cmd": NAME, ...}``; every answer is one or
more JSON objects, one per line, each with ``"ok"``: ``{"ok": false, "error": "..."}`` for a refusal (bad
JSON, unknown command, invalid argument). A connection may carry several requests in turn. The commands
themselves (``status``, ``start``, ``follow``, ``cancel``) are the robot's (`atemr.robot.control`); this
module only frames, dispatches and serves them, one thread per connection.
"""

from __future__ import annotations

import contextlib
import difflib
import json
import logging
import os
import select
import socket
import stat
import tempfile
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from atemr.config import Config
from atemr.errors import AtemrError, ConfigError, ControlError

log = logging.getLogger(__name__)

#: The longest request line accepted (a mission document is well under this).
MAX_LINE_BYTES = 1 << 20
#: Longest path a Unix socket can have (``sun_path`` is 108 bytes on Linux, with its terminating NUL).
MAX_PATH_BYTES = 107
#: Seconds a probe of an existing socket waits before calling it stale.
PROBE_TIMEOUT_S = 1.0


def control_socket_path(config: Config) -> Path:
    """The control socket: ``control.socket`` or ``data_dir/control.sock``."""
    return config.control.socket or config.data_dir / "control.sock"


class ControlConnection:
    """One client's connection, as a command handler sees it: send answers, notice the client leaving."""

    def __init__(self, sock: socket.socket, number: int) -> None:
        self.sock = sock
        self.number = number
        self._lock = threading.Lock()
        self._gone = False
        #: Clear while a command runs on this connection (stopping the server lets it finish its answers).
        self.idle = threading.Event()
        self.idle.set()

    def send(self, message: Mapping[str, Any]) -> bool:
        """Write one JSON line; False (and nothing raised) once the client has gone."""
        data = (json.dumps(message, default=str) + "\n").encode("utf-8")
        with self._lock:
            if self._gone:
                return False
            try:
                self.sock.sendall(data)
            except OSError:
                self._gone = True
                return False
        return True

    def gone(self) -> bool:
        """True when the client closed its end (checked without blocking)."""
        if self._gone:
            return True
        try:
            readable, _, _ = select.select([self.sock], [], [], 0)
            if readable and self.sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b"":
                self._gone = True
        except BlockingIOError:
            pass
        except (OSError, ValueError):
            self._gone = True
        return self._gone


#: A command: the request (already a JSON object) and the connection to answer on.
Handler = Callable[[dict[str, Any], ControlConnection], None]


def refusal(message: str) -> dict[str, Any]:
    """The answer to a request that is refused: nothing was done."""
    return {"ok": False, "error": message}


class ControlServer:
    """Serves ``commands`` on the Unix socket ``path`` from its own threads (`start` ... `stop`)."""

    def __init__(self, path: Path, commands: Mapping[str, Handler], *, name: str = "control") -> None:
        self.path = Path(path)
        self.commands = dict(commands)
        self.name = name
        self._listener: socket.socket | None = None
        self._identity: tuple[int, int] | None = None
        self._wake_r, self._wake_w = -1, -1
        self._thread: threading.Thread | None = None
        self._connections: dict[int, tuple[ControlConnection, threading.Thread]] = {}
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._numbers = 0

    @property
    def stopping(self) -> bool:
        return self._stopping.is_set()

    @property
    def serving(self) -> bool:
        return self._listener is not None and not self.stopping

    # -- lifecycle ---------------------------------------------------------------------------------
    def start(self) -> None:
        """Bind the socket (replacing a stale one) and start accepting connections."""
        if self._listener is not None:
            return
        path = self.path
        if len(os.fsencode(path)) > MAX_PATH_BYTES:
            raise ConfigError(f"the control socket path is {len(os.fsencode(path))} bytes, more than the "
                              f"{MAX_PATH_BYTES} a Unix socket allows: set a shorter control.socket "
                              f"(ATEMR_CONTROL__SOCKET) or a shorter data_dir", path=f"control.socket {path}")
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        stale = _check_existing(path)
        private = tempfile.mkdtemp(prefix=".ctl-", dir=path.parent)  # mode 0700: nobody else can reach inside
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            temporary = os.path.join(private, "s")
            listener.bind(temporary)
            os.chmod(temporary, 0o600)
            listener.listen(8)
            os.replace(temporary, path)  # atomic: replaces a stale socket too
        except OSError as exc:
            listener.close()
            raise ControlError(f"cannot serve the control socket {path}: {exc.strerror or exc}") from None
        finally:
            _remove(os.path.join(private, "s"))
            os.rmdir(private)
        if stale:
            log.warning("replaced the stale control socket %s (a robot stopped without removing it)", path)
        info = os.stat(path)
        self._identity = (info.st_dev, info.st_ino)
        self._listener = listener
        self._wake_r, self._wake_w = os.pipe()
        self._stopping.clear()
        self._thread = threading.Thread(target=self._accept_loop, name=f"{self.name}-accept", daemon=True)
        self._thread.start()
        log.info("control socket: %s (mode 0600, this user only)", path)

    def stop(self, *, join_s: float = 5.0) -> None:
        """Stop accepting, close every connection, remove the socket if it is still ours; idempotent."""
        if self._listener is None:
            return
        self._stopping.set()
        os.write(self._wake_w, b"x")
        if self._thread is not None:
            self._thread.join(join_s)
        with self._lock:
            connections = list(self._connections.values())
        for connection, _ in connections:
            connection.idle.wait(join_s)  # a command being answered finishes (its handler sees `stopping`)
            with contextlib.suppress(OSError):
                connection.sock.shutdown(socket.SHUT_RDWR)  # wakes its thread out of a blocking read
        for _, thread in connections:
            thread.join(join_s)
        self._listener.close()
        self._listener = None
        for fd in (self._wake_r, self._wake_w):
            os.close(fd)
        self._wake_r = self._wake_w = -1
        with contextlib.suppress(FileNotFoundError):
            info = os.stat(self.path)
            if (info.st_dev, info.st_ino) == self._identity:
                os.unlink(self.path)

    # -- threads -----------------------------------------------------------------------------------
    def _accept_loop(self) -> None:
        assert self._listener is not None
        while not self.stopping:
            readable, _, _ = select.select([self._listener.fileno(), self._wake_r], [], [])
            if self._wake_r in readable or self.stopping:
                return
            try:
                sock, _ = self._listener.accept()
            except OSError:
                continue
            with self._lock:
                self._numbers += 1
                connection = ControlConnection(sock, self._numbers)
                thread = threading.Thread(target=self._serve, args=(connection,), daemon=True,
                                          name=f"{self.name}-conn-{connection.number}")
                self._connections[connection.number] = (connection, thread)
            thread.start()

    def _serve(self, connection: ControlConnection) -> None:
        try:
            with connection.sock.makefile("rb") as lines:
                while not self.stopping:
                    try:
                        line = lines.readline(MAX_LINE_BYTES + 1)
                    except OSError:
                        return
                    if not line:
                        return
                    if len(line) > MAX_LINE_BYTES:
                        connection.send(refusal(f"request longer than {MAX_LINE_BYTES} bytes; connection closed"))
                        return
                    if line.strip():
                        self.dispatch(line, connection)
        finally:
            connection.sock.close()
            with self._lock:
                self._connections.pop(connection.number, None)

    def dispatch(self, line: bytes, connection: ControlConnection) -> None:
        """Decode one request line and run its command; every failure becomes a refusal on the wire."""
        request, why = parse_request(line, self.commands)
        if request is None:
            connection.send(refusal(why or "bad request"))
            return
        connection.idle.clear()
        try:
            self.commands[request["cmd"]](request, connection)
        except AtemrError as exc:
            connection.send(refusal(str(exc)))
        except Exception as exc:  # a bug in one command must not take the channel down
            log.exception("control command %r failed", request["cmd"])
            connection.send(refusal(f"internal error in '{request['cmd']}': {type(exc).__name__}: {exc}"))
        finally:
            connection.idle.set()


def parse_request(line: bytes, commands: Mapping[str, Handler]) -> tuple[dict[str, Any] | None, str | None]:
    """(the request, None) or (None, why it is refused): JSON, an object, a known ``cmd``."""
    try:
        request = json.loads(line.decode("utf-8").rstrip("\r\n"))
    except UnicodeDecodeError as exc:
        return None, f"bad request: not UTF-8 ({exc.reason} at byte {exc.start})"
    except json.JSONDecodeError as exc:
        return None, f"bad JSON at line {exc.lineno} column {exc.colno}: {exc.msg}"
    if not isinstance(request, dict):
        return None, f"a request is a JSON object {{\"cmd\": ...}}, got {type(request).__name__}"
    name = request.get("cmd")
    if not isinstance(name, str):
        return None, f"a request needs \"cmd\" (one of {', '.join(sorted(commands))})"
    if name not in commands:
        close = difflib.get_close_matches(name, list(commands), n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        return None, f"unknown command '{name}'{hint}; commands: {', '.join(sorted(commands))}"
    return request, None


def _check_existing(path: Path) -> bool:
    """True when ``path`` is a stale socket to replace; raises when it must not be touched."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return False
    if not stat.S_ISSOCK(info.st_mode):
        raise ControlError(f"{path} exists and is not a socket: refusing to replace it (move it away or set "
                           f"control.socket)")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    probe.settimeout(PROBE_TIMEOUT_S)
    try:
        probe.connect(str(path))
    except (ConnectionRefusedError, FileNotFoundError):
        return True
    except OSError as exc:
        raise ControlError(f"cannot check the existing control socket {path}: {exc.strerror or exc}") from None
    finally:
        probe.close()
    raise ControlError(f"another robot is already running with the control socket {path}: stop it first, or "
                       f"give this one another data_dir or control.socket")


def _remove(path: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


__all__ = ["ControlConnection", "ControlServer", "Handler", "control_socket_path", "parse_request", "refusal"]
