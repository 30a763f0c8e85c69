"""The captive portal (thesis 3.6.3 "Captive Portal & IP Address Interface"): a small Flask app.

A person joins the board's access point (``ATEMR-Connect``), the phone opens this portal: a "join
network" page where CONNECT sends the SSID and password to the primary core over CAN (0x154/0x155), and
a "VIEW IP" page where REFRESH asks the primary for its address (empty 0x156) and shows the last answer
(as on the board, a fresh answer shows on the next refresh). Bad input (empty SSID, password shorter
than 8 or longer than 63 bytes) is refused on the page and nothing is sent.

The portal only answers while the board has it active (120 s after entering CONFIG); otherwise every
page is 503. Any unknown URL redirects to the portal's first page, which is what makes phones show it
as a captive portal. Forms carry a CSRF token. `PortalHost` serves the app on its own port (default
5001) exactly while the portal is active, in one server thread at the edge of the system.
"""

from __future__ import annotations

import logging
import secrets
import threading
from typing import Any

from flask import Blueprint, Flask, abort, current_app, redirect, render_template, request, session, url_for
from werkzeug.exceptions import HTTPException
from werkzeug.serving import BaseWSGIServer, make_server
from werkzeug.wrappers import Response

from atemr.errors import AtemrError
from atemr.io.network import credential_problems
from atemr.io.secondary_emulator.board import SecondaryCore

log = logging.getLogger("secondary_core.portal")  # the name it logged under before it moved here

DEFAULT_PORT = 5001

bp = Blueprint("portal", __name__, template_folder="templates")


def _core() -> SecondaryCore:
    core: SecondaryCore = current_app.extensions["secondary_core"]
    return core


def _csrf_token() -> str:
    token = session.get("csrf_token")
    if not isinstance(token, str):
        token = secrets.token_urlsafe(24)
        session["csrf_token"] = token
    return token


def _page(template: str, status: int = 200, **context: Any) -> tuple[str, int]:
    core = _core()
    left = core.portal_left_s
    html = render_template(
        template, robot_name=core.config.robot_name, csrf_token=_csrf_token(),
        portal_left_s=int(left) if left is not None else None, **context,
    )
    return html, status


@bp.before_app_request
def _only_while_active() -> tuple[str, int] | None:
    if not _core().portal_active:
        return _page("portal/closed.html", 503,
                     message="Press the robot's power button briefly to open the CONFIG screen and this portal.")
    if request.method == "POST":
        sent = request.form.get("csrf_token", "")
        expected = session.get("csrf_token")
        if not isinstance(expected, str) or not secrets.compare_digest(sent, expected):
            abort(400, description="The form expired: reload the page and try again.")
    return None


@bp.get("/favicon.ico")
def favicon() -> tuple[str, int]:
    return "", 204  # no icon; without this route the browser's request would be redirected to the portal


@bp.get("/")
def index() -> tuple[str, int]:
    return _page("portal/index.html", ssid="", errors=[])


@bp.post("/connect")
def connect() -> tuple[str, int]:
    ssid = request.form.get("ssid", "")
    password = request.form.get("password", "")
    problems = credential_problems(ssid, password)
    if not problems:
        try:
            _core().send_wifi(ssid, password)
        except AtemrError as exc:
            problems = [str(exc)]
    if problems:
        log.info("portal: credentials refused: %s", "; ".join(problems))
        return _page("portal/index.html", 400, ssid=ssid, errors=problems)
    return _page("portal/sent.html", ssid=ssid)


@bp.get("/ip")
def ip_page() -> tuple[str, int]:
    return _page("portal/ip.html", ip=_core().robot_ip or "0.0.0.0", asked=False)


@bp.post("/ip/refresh")
def refresh_ip() -> tuple[str, int]:
    core = _core()
    core.request_ip()
    return _page("portal/ip.html", ip=core.robot_ip or "0.0.0.0", asked=True)


def create_portal_app(core: SecondaryCore, *, test_config: dict[str, Any] | None = None) -> Flask:
    """The portal for ``core`` (Flask application factory; ``test_config`` overrides settings in tests)."""
    app = Flask(__name__)
    app.config.update(
        SECRET_KEY=secrets.token_hex(32),
        SESSION_COOKIE_HTTPONLY=True,
        SESSION_COOKIE_SAMESITE="Lax",
        MAX_CONTENT_LENGTH=4096,
    )
    if test_config:
        app.config.update(test_config)
    app.extensions["secondary_core"] = core
    app.register_blueprint(bp)

    @app.errorhandler(404)
    def _to_portal(exc: HTTPException) -> Response:
        # Captive-portal behaviour: phones probe fixed URLs (generate_204, hotspot-detect.html, ...);
        # answering every unknown URL with the portal makes them open it.
        return redirect(url_for("portal.index"))

    return app


class PortalHost:
    """Serves the portal app on ``host:port`` exactly while ``core.portal_active`` (a scheduler component).

    Tick it at a few Hz. The server runs in its own thread; starting or stopping it never blocks the tick
    for long (stopping waits for the server thread in the background).
    """

    def __init__(self, core: SecondaryCore, *, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 app: Flask | None = None, name: str = "secondary_portal") -> None:
        self.name = name
        self.core = core
        self.host = host
        self.port = port
        self.app = app or create_portal_app(core)
        self._server: BaseWSGIServer | None = None
        self._thread: threading.Thread | None = None
        self._stopping: list[threading.Thread] = []
        self.error: str | None = None

    @property
    def serving(self) -> bool:
        return self._server is not None

    @property
    def url(self) -> str | None:
        if self._server is None:
            return None
        return f"http://{self.host}:{self._server.server_port}/"

    def tick(self, now: float) -> None:
        if self.core.portal_active and self._server is None:
            self._start_server()
        elif not self.core.portal_active and self._server is not None:
            self._stop_server(wait=False)

    def shutdown(self) -> None:
        """Stop the server (if serving) and wait for every server thread to end."""
        self._stop_server(wait=True)
        for thread in self._stopping:
            thread.join(timeout=5)
        self._stopping.clear()

    def _start_server(self) -> None:
        try:
            server = make_server(self.host, self.port, self.app, threaded=True)
        except OSError as exc:
            if self.error is None:
                log.error("captive portal cannot listen on %s:%d: %s", self.host, self.port, exc)
            self.error = f"cannot listen on {self.host}:{self.port}: {exc}"
            return
        self.error = None
        self._server = server
        self._thread = threading.Thread(target=server.serve_forever, name="secondary-portal", daemon=True)
        self._thread.start()
        log.info("captive portal serving on %s", self.url)

    def _stop_server(self, *, wait: bool) -> None:
        server, thread = self._server, self._thread
        self._server = self._thread = None
        if server is None:
            return

        def stop() -> None:
            server.shutdown()
            server.server_close()
            if thread is not None:
                thread.join(timeout=5)
            log.info("captive portal stopped")

        if wait:
            stop()
        else:
            stopper = threading.Thread(target=stop, name="secondary-portal-stop", daemon=True)
            stopper.start()
            self._stopping = [t for t in self._stopping if t.is_alive()] + [stopper]
