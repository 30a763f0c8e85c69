"""The dashboard as a robot component: serves the app in a background thread and pushes state at 10 Hz.

``start()`` binds ``ui.host:ui.port`` (port 0 picks a free port, see `port`) and serves Flask-SocketIO
(threading async mode) with werkzeug's threaded server, bounded (`BoundedWSGIServer`: at most
``ui.max_connections`` connections at once, the rest answered 503 at once; time limits on reading a
request), in a daemon thread; ``tick(now)`` — scheduled by
the robot at `PUSH_RATE_HZ` — sends the gateway's snapshot to every logged-in browser and camera frames
to those watching; ``shutdown()`` ends the camera streams, stops the server and joins the thread
(idempotent). With ``ui.message_queue`` set, ``start()`` first checks the queue is reachable. The pushes ride on
the robot's scheduler, so there is no timer thread and no wall-clock sleep here.
"""

from __future__ import annotations

import ipaddress
import logging
import re
import socket
import ssl
import threading
from typing import Any

from flask import Flask
from werkzeug.serving import ThreadedWSGIServer, WSGIRequestHandler

from atemr.clock import Clock
from atemr.config import Config
from atemr.errors import HardwareError
from atemr.io.map_store import MapStore
from atemr.ui import sockets
from atemr.ui.app import create_app
from atemr.ui.gateway import RobotGateway
from atemr.ui.message_queue import check_reachable
from atemr.ui.state import STATE_RATE_HZ
from atemr.ui.tls import server_context
from atemr.ui.users import HASH_METHOD

log = logging.getLogger(__name__)


def is_loopback(host: str) -> bool:
    """True for addresses only this machine reaches (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:  # a host name: it may resolve to anything
        return False


def exposure_warning(host: str, port: int) -> str | None:
    """What listening on ``host`` exposes, or None when only this machine can reach it."""
    if is_loopback(host):
        return None
    return (f"the dashboard listens on {host}, not only on this machine: anyone who can reach port {port} there "
            "sees the login page, and a logged-in user drives the robot and watches its camera over plain HTTP; "
            "put it behind a TLS reverse proxy or keep it on 127.0.0.1")
http_log = logging.getLogger("atemr.ui.http")


#: Responses up to this size are read out and closed before werkzeug writes them (see `CloseEarly`).
CLOSE_EARLY_MAX_BYTES = 8 * 1024 * 1024


class CloseEarly:
    """WSGI middleware: reads small responses of known length into memory and closes them at once.

    werkzeug's development server skips ``close()`` of a response when the browser has already dropped the
    connection (its clean-up fails on the closed socket first), which leaks the open file of every static
    asset or download a navigating page abandons. Reading out small bodies first closes them on every
    path; large ones (videos) still stream.
    """

    def __init__(self, app: Any, max_bytes: int = CLOSE_EARLY_MAX_BYTES) -> None:
        self.app = app
        self.max_bytes = max_bytes

    def __call__(self, environ: dict[str, Any], start_response: Any) -> Any:
        length: list[int | None] = [None]

        def capture(status: str, headers: list[tuple[str, str]], exc_info: Any = None) -> Any:
            length[0] = 0 if _has_no_body(environ, status) else next(
                (int(v) for k, v in headers if k.lower() == "content-length" and v.isdigit()), None)
            return start_response(status, headers, exc_info)

        body = self.app(environ, capture)
        if length[0] is None or length[0] > self.max_bytes or not hasattr(body, "close"):
            return body
        try:
            return [b"".join(body)]
        finally:
            body.close()


def _has_no_body(environ: dict[str, Any], status: str) -> bool:
    """Whether HTTP forbids this response a body: a HEAD request's, or a 1xx, 204 or 304 (a browser's
    revalidated cached asset), which carry no Content-Length although the app may hold an open file."""
    code = int(status.split(None, 1)[0])
    return environ.get("REQUEST_METHOD") == "HEAD" or 100 <= code < 200 or code in (204, 304)


#: Seconds a client may take to send each line of a request's head (one that sends nothing is dropped).
HEADER_TIMEOUT_S = 10.0
#: Seconds one read or write of a body may block (a stalled reader of a stream is dropped); WebSockets: none.
IO_TIMEOUT_S = 60.0
_BUSY_BODY = b"The dashboard is serving as many connections as it may: try again in a moment.\n"
BUSY_RESPONSE = (
    b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\nRetry-After: 1\r\n"
    b"Content-Length: " + str(len(_BUSY_BODY)).encode() + b"\r\nConnection: close\r\n\r\n" + _BUSY_BODY
)


_TOKEN_IN_QUERY = re.compile(r"([?&]token=)[^&\s\"]+")


def hide_tokens(line: str) -> str:
    """A request line without the screen's device token (``/screen?token=...``): logs are read by more
    people than the token is meant for."""
    return _TOKEN_IN_QUERY.sub(r"\1<hidden>", line)


class _RequestHandler(WSGIRequestHandler):
    """werkzeug's handler, logging through ``atemr.ui.http`` (requests at DEBUG) instead of attaching its
    own stderr handler, so the robot's log configuration decides what is shown; with time limits on the
    socket: `HEADER_TIMEOUT_S` while the request's head arrives, `IO_TIMEOUT_S` for its body and response,
    none for a WebSocket (it idles between messages by design)."""

    def log(self, type: str, message: str, *args: Any) -> None:
        level = logging.DEBUG if type == "info" else logging.WARNING
        http_log.log(level, "%s %s", self.address_string(), hide_tokens(message % args))

    def handle_one_request(self) -> None:
        self.connection.settimeout(HEADER_TIMEOUT_S)
        super().handle_one_request()

    def run_wsgi(self) -> None:
        websocket = self.headers.get("Upgrade", "").strip().lower() == "websocket"
        self.connection.settimeout(None if websocket else IO_TIMEOUT_S)
        super().run_wsgi()
        if websocket:
            # The connection was the WebSocket's: once it has ended, what follows on it is not HTTP. Kept open
            # (HTTP/1.1 keep-alive), the client's closing frames were parsed as a request ("400 Bad request
            # syntax") and it waited its close timeout (3 s for python clients) for a closing frame that never came.
            self.close_connection = True


#: How often a serving loop looks for a request to stop. socketserver's default, 0.5 s, made every stop of the
#: dashboard (the robot's SIGTERM, a test's teardown) wait up to half a second for nothing; a poll that wakes 20
#: times a second costs no measurable CPU.
SHUTDOWN_POLL_S = 0.05


class BoundedWSGIServer(ThreadedWSGIServer):
    """werkzeug's threaded WSGI server (what Flask-SocketIO's threading mode runs on: WebSockets through
    simple-websocket, streamed responses) with at most ``max_connections`` connections served at once.

    Each accepted connection takes a slot of a bounded semaphore and is served in its own thread; when no
    slot is free the connection gets a fixed ``503 Service Unavailable`` (``Retry-After: 1``) written by
    the accepting thread and is closed: no thread, no queue, no parsing. A WebSocket or a camera stream
    holds its slot for as long as it lasts; werkzeug closes every other connection after one request.
    """

    def __init__(self, host: str, port: int, app: Any, *, max_connections: int,
                 handler: type[WSGIRequestHandler] | None = None, ssl_context: ssl.SSLContext | None = None) -> None:
        self.max_connections = max_connections
        self.refused = 0
        self._slots = threading.BoundedSemaphore(max_connections)
        super().__init__(host, port, app, handler=handler, ssl_context=ssl_context)

    def serve_forever(self, poll_interval: float = SHUTDOWN_POLL_S) -> None:
        """Serve until `shutdown`, looking for its request every ``poll_interval`` seconds."""
        super().serve_forever(poll_interval=poll_interval)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            self.refused += 1
            self._refuse(request)
            return
        try:
            threading.Thread(target=self._serve, args=(request, client_address), name="atemr-dashboard-conn",
                             daemon=True).start()
        except RuntimeError:  # no thread could be started: as busy as it gets
            self._slots.release()
            self.refused += 1
            self._refuse(request)

    def _serve(self, request: Any, client_address: Any) -> None:
        try:
            self.process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def _refuse(self, request: socket.socket) -> None:
        try:
            request.setblocking(False)
            try:  # read what has arrived: closing over unread bytes would reset the connection before the 503
                while request.recv(65536):
                    pass
            except (BlockingIOError, InterruptedError):
                pass
            request.send(BUSY_RESPONSE)
        except OSError:
            pass
        finally:
            self.shutdown_request(request)


#: How often the robot should tick the server (state pushes per second).
PUSH_RATE_HZ = STATE_RATE_HZ  # the rate the state contract promises the pages


class DashboardServer:
    """A scheduler component running the operator dashboard.

    Wire it as ``robot.add(DashboardServer(config, gateway, clock=clock), PUSH_RATE_HZ)``.
    """

    name = "dashboard"

    def __init__(
        self,
        config: Config,
        gateway: RobotGateway | None,
        *,
        clock: Clock | None = None,
        hash_method: str = HASH_METHOD,
        map_store: MapStore | None = None,
    ) -> None:
        self.config = config
        self.gateway = gateway
        if map_store is None:  # a dashboard without a robot (atemr dashboard): the configured map limits still hold
            map_store = MapStore(config.data_dir, max_cells=config.ui.max_map_cells,
                                 max_upload_bytes=int(config.ui.max_upload_mb * 1024 * 1024))
        self.app: Flask = create_app(config, gateway, clock=clock, hash_method=hash_method, map_store=map_store)
        self._server: BoundedWSGIServer | None = None
        self._thread: threading.Thread | None = None
        self.pushes = 0

    @property
    def port(self) -> int:
        """The bound port (the real one when the configuration asked for 0)."""
        if self._server is None:
            raise HardwareError("the dashboard is not started", component=self.name)
        return int(self._server.server_port)

    @property
    def url(self) -> str:
        host = self.config.ui.host
        host = {"0.0.0.0": "127.0.0.1", "::": "::1"}.get(host, host)  # every interface: this machine's is one
        scheme = "https" if self.config.ui.tls_cert is not None else "http"
        return f"{scheme}://[{host}]:{self.port}" if ":" in host else f"{scheme}://{host}:{self.port}"

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        if self._server is not None:
            return
        if self.config.ui.message_queue is not None:
            check_reachable(self.config.ui.message_queue, self.name)
        ui = self.config.ui
        tls = None if ui.tls_cert is None or ui.tls_key is None else server_context(ui.tls_cert, ui.tls_key)
        self.app.extensions["atemr.stopping"].clear()
        try:
            self._server = BoundedWSGIServer(
                self.config.ui.host, self.config.ui.port, CloseEarly(self.app),
                max_connections=self.config.ui.max_connections, handler=_RequestHandler, ssl_context=tls,
            )
        except (OSError, SystemExit) as exc:  # werkzeug exits (!) when the port is taken
            why = exc.strerror if isinstance(exc, OSError) else "the address is in use or not available"
            raise HardwareError(
                f"cannot listen on {self.config.ui.host}:{self.config.ui.port}: {why}", component=self.name
            ) from None
        self._thread = threading.Thread(target=self._server.serve_forever, name="atemr-dashboard", daemon=True)
        self._thread.start()
        exposed = exposure_warning(self.config.ui.host, self.port)
        if exposed:
            log.warning("%s", exposed)
        if self.app.extensions["atemr.users"].needs_root_password():
            log.warning(
                "the dashboard has no admin password yet: open %s on this machine or run "
                "'atemr user set-password admin'", self.url,
            )
        log.info("dashboard on %s", self.url)

    def tick(self, now: float) -> None:
        """Push the state (and camera frames) to the connected browsers."""
        if self._server is None:
            return
        sockets.push(self.app, self.gateway)
        self.pushes += 1

    def shutdown(self) -> None:
        server, thread = self._server, self._thread
        self._server = self._thread = None
        self.app.extensions["atemr.stopping"].set()  # ends the open camera streams
        self.app.extensions["atemr.drive_video"].shutdown()  # and the WebRTC ones, with their loop
        if server is not None:
            server.shutdown()  # no new connection from here on (a page retrying now would stay on a dead server)
            sockets.disconnect_all(self.app)  # pages see theirs end (they said ONLINE to a dead server)
            server.server_close()
        if thread is not None:
            thread.join(timeout=5.0)
