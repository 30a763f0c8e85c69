"""The dashboard's application factory: `create_app` builds a Flask app with its Socket.IO server.

As in Flask's flaskr tutorial there is no app object at import time; each call makes a new app with
its own user store, rate limiter and Socket.IO server, so tests get a fresh one per test. One blueprint
per page group (auth, control, mapping, settings, media, agent), each with its templates, static files and
Socket.IO handlers beside it.
"""

from __future__ import annotations

import os
import secrets
import threading
from datetime import timedelta
from pathlib import Path
from typing import Any

from flask import Flask, jsonify, redirect, render_template, request, url_for
from flask_socketio import SocketIO
from markupsafe import escape
from werkzeug.exceptions import HTTPException
from werkzeug.wrappers import Response

from atemr import __version__
from atemr.clock import Clock, WallClock
from atemr.config import Config
from atemr.errors import ConfigError
from atemr.io.map_store import MapStore
from atemr.ui import sockets
from atemr.ui.gateway import RobotGateway
from atemr.ui.media import files as media_files
from atemr.ui.payload import PacketJSON
from atemr.ui.screens import ScreenStore
from atemr.ui.security import (
    LoginRateLimiter,
    TrustedHostMiddleware,
    check_csrf,
    csrf_token,
    current_user,
    html_response,
    may,
    refusal,
    trusted_hosts,
    wants_json,
)
from atemr.ui.state import STATE_RATE_HZ
from atemr.ui.users import HASH_METHOD, PasswordHashBusy, UserStore

#: Endpoints reachable before the root admin has a password (everything else redirects to first start).
FIRST_START_OPEN = frozenset({"auth.first_start", "static", "favicon"})


def database_path(config: Config) -> Path:
    """The users database: ``ui.database`` or ``data_dir/users.sqlite3``."""
    return config.ui.database or config.data_dir / "users.sqlite3"


def secret_key(config: Config) -> bytes:
    """The session signing key, read from ``ui.secret_key_file`` (default ``data_dir/ui.key``) and
    generated there (mode 0600) on the first start, so sessions survive a restart."""
    path = config.ui.secret_key_file or config.data_dir / "ui.key"
    try:
        if path.exists():
            key = path.read_bytes()
            if len(key) < 32:
                raise ConfigError(f"the secret key file holds {len(key)} bytes; delete it to generate a new one",
                                  file=path)
            return key
        path.parent.mkdir(parents=True, exist_ok=True)
        key = secrets.token_bytes(48)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as out:
            out.write(key)
        return key
    except OSError as exc:
        raise ConfigError(f"cannot read or create the secret key file: {exc.strerror}", file=path) from None


def create_app(
    config: Config | None = None,
    gateway: RobotGateway | None = None,
    *,
    clock: Clock | None = None,
    hash_method: str = HASH_METHOD,
    map_store: MapStore | None = None,
) -> Flask:
    """A dashboard app for ``config`` talking to the robot through ``gateway`` (None: pages work, every
    robot command is refused with "no robot is connected").

    ``clock`` times the login rate limit (wall clock by default); ``hash_method`` lets tests use cheaper
    scrypt parameters ("scrypt:1024:8:1"); ``map_store`` is the robot's map store (by default one over
``data_dir/maps`` with the built-in maps), through which maps are listed, uploaded and deleted.
    The Socket.IO server is ``app.extensions["socketio"]``.
    """
    config = config or Config()
    app = Flask(__name__, static_folder="static", template_folder="templates")
    lifetime = timedelta(hours=12)
    app.config.update(
        SECRET_KEY=secret_key(config),
        SESSION_COOKIE_NAME="atemr_session",
        SESSION_COOKIE_HTTPONLY=True,
        SESSION_COOKIE_SAMESITE="Lax",
        SESSION_COOKIE_SECURE=config.ui.tls_cert is not None,  # over HTTPS, never sent in the clear
        PERMANENT_SESSION_LIFETIME=lifetime,
        MAX_CONTENT_LENGTH=int(config.ui.max_upload_mb * 1024 * 1024),
        ATEMR_CONFIG=config,
        ATEMR_VERSION=__version__,
    )
    app.extensions["atemr.users"] = UserStore(database_path(config), hash_method=hash_method,
                                              session_lifetime_s=lifetime.total_seconds())
    app.extensions["atemr.screens"] = ScreenStore(database_path(config))
    app.extensions["atemr.gateway"] = gateway
    clock = clock or WallClock()
    app.extensions["atemr.limiter"] = LoginRateLimiter(
        clock, max_failures=config.ui.login_max_failures, lockout_s=config.ui.login_lockout_s,
        max_failures_per_address=config.ui.login_max_failures_per_address,
    )
    # New accounts: as many per address and lockout period as failed logins per user.
    app.extensions["atemr.register_limiter"] = LoginRateLimiter(
        clock, max_failures=config.ui.login_max_failures, lockout_s=config.ui.login_lockout_s
    )
    maps = map_store or MapStore(config.data_dir, max_cells=config.ui.max_map_cells)
    app.extensions["atemr.maps"] = maps
    app.extensions["atemr.media"] = media_files.MediaStore(
        config.data_dir, maps, in_use=gateway.files_in_use if gateway is not None else tuple)
    app.extensions["atemr.stopping"] = threading.Event()  # set by the server's shutdown: streams end

    app.before_request(check_csrf)
    app.after_request(_security_headers)
    app.before_request(_first_start_gate)
    app.register_error_handler(PasswordHashBusy, _busy)
    app.register_error_handler(404, _not_found)
    app.register_error_handler(405, _not_found)
    app.jinja_env.globals["csrf_token"] = csrf_token
    app.context_processor(_template_globals)

    from atemr.ui.agent import bp as agent_bp
    from atemr.ui.auth import bp as auth_bp
    from atemr.ui.control import bp as control_bp
    from atemr.ui.mapping import bp as mapping_bp
    from atemr.ui.media import bp as media_bp
    from atemr.ui.routines import bp as routines_bp
    from atemr.ui.screen import bp as screen_bp
    from atemr.ui.settings import bp as settings_bp

    for bp in (auth_bp, control_bp, mapping_bp, settings_bp, media_bp, agent_bp, routines_bp, screen_bp):
        app.register_blueprint(bp)
    app.add_url_rule("/", "index", lambda: redirect(url_for("control.page")))
    # Browsers ask for /favicon.ico on their own (downloads, bookmarks) whatever the pages link.
    app.add_url_rule("/favicon.ico", "favicon", lambda: app.send_static_file("favicon.svg"))

    socketio = SocketIO(
        app,
        async_mode="threading",
        cors_allowed_origins=None,  # None = same origin only; never "*"
        manage_session=True,
        message_queue=config.ui.message_queue,
        max_http_buffer_size=1_000_000,  # events are small; uploads go over HTTP with their own limit
        json=PacketJSON,  # huge integer literals are refused by the payload checks, not logged as errors
        logger=False,
        engineio_logger=False,
    )
    from atemr.ui.agent.events import events as agent_events
    from atemr.ui.call import events as call
    from atemr.ui.control.events import events as control_events
    from atemr.ui.drive_video import events as drive_video
    from atemr.ui.mapping.events import events as mapping_events

    sockets.init_app(app, socketio, groups=(control_events, mapping_events, agent_events, call.events,
                                            drive_video.events))
    call.init_app(app)
    drive_video.init_app(app, gateway)
    # Outermost: a foreign Host header (DNS rebinding) reaches neither the pages nor Socket.IO.
    app.wsgi_app = TrustedHostMiddleware(  # type: ignore[method-assign]
        app.wsgi_app, trusted_hosts(config.ui.host, config.ui.trusted_hosts)
    )
    return app


#: What a carer reads for an address that is not a page (a mistyped or an old bookmark) or a page asked wrongly.
_NOT_FOUND = {
    404: ("This page does not exist", "The address may be mistyped, or the page has moved."),
    405: ("This page cannot do that", "The page was asked in a way it does not answer; start again from a page."),
}


def _not_found(exc: HTTPException) -> Response:
    """A page in the dashboard's own layout (readable on a phone, with the way back), or JSON for an API call."""
    code = exc.code or 404
    title, text = _NOT_FOUND[code]
    if exc.description != type(exc).description:  # a view said what is missing (abort(404, description=...))
        text = str(exc.description)
    if wants_json():
        response = jsonify({"ok": False, "reason": exc.description or title})
        response.status_code = code
        return response
    return html_response(render_template("not_found.html", title=title, text=text), code)


def _busy(exc: PasswordHashBusy) -> Response:
    """Every password-hashing slot is taken: "busy, try again in a second", at once (no queue)."""
    return html_response(f"<p>{escape(str(exc))}</p>", 503, headers={"Retry-After": "1"})


#: Scripts, styles, frames and connections from this origin only; images also as data: (camera frames).
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "connect-src 'self'; frame-ancestors 'none'; form-action 'self'; base-uri 'none'; object-src 'none'"
)


def _security_headers(response: Response) -> Response:
    """No framing (clickjacking), no MIME sniffing, no inline script, no referrer leaks."""
    response.headers.setdefault("Content-Security-Policy", CONTENT_SECURITY_POLICY)
    response.headers.setdefault("X-Content-Type-Options", "nosniff")
    response.headers.setdefault("X-Frame-Options", "DENY")
    response.headers.setdefault("Referrer-Policy", "same-origin")
    return response


def _first_start_gate() -> Response | None:
    """Until the root admin has a password, every page leads to the first-start page."""
    from atemr.ui.security import user_store

    if request.endpoint in FIRST_START_OPEN or (request.endpoint or "").endswith(".static"):
        return None
    if request.path.startswith("/socket.io"):
        return None
    if user_store().needs_root_password():
        return redirect(url_for("auth.first_start"))
    return None


def _template_globals() -> dict[str, Any]:
    from flask import current_app

    config: Config = current_app.config["ATEMR_CONFIG"]
    own = current_app.extensions["atemr.gateway"] is not None
    return {"current_user": current_user(), "version": __version__, "simulation": config.simulation,
            "robot_name": config.secondary.robot_name if own else "", "may": may, "refusal": refusal,
            "state_period_ms": round(1000 / STATE_RATE_HZ)}
