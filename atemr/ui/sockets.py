"""Socket.IO plumbing shared by the page groups: the connect check, per-event role checks, the pushes.

A client without a logged-in session with at least the ``user`` role is refused in the connect
handler. Every event is declared in its page group's `EventGroup` (handed to `create_app` as a blueprint
is), which re-reads the user from the database (so a revoked role takes effect on the next event), checks
the event's permission if it names one, validates nothing else and turns the handler's `CommandResult` (or
an `AtemrError`) into the acknowledgement the page shows; a malformed payload is refused with one WARNING
line. Each socket remembers its session token: logging out closes that session's
sockets, a password or role change or a removal all of that user's sockets at once (`disconnect_session`,
`disconnect_user`), and the pushes check twice a second (`REVOKE_CHECK_S`) that every socket's session is
still live in the users database, so a change made elsewhere (``atemr user set-password``, another worker)
closes the sockets within a second too.

Rooms: every accepted client joins ``operators`` (state at 10 Hz); a client that turned its camera on
also joins ``camera`` (JPEG frames, base64 in JSON, only while someone watches), and the Agent view joins
``agent`` (the agent's snapshot: lifecycle, trees, transitions).

With ``ui.message_queue`` set, ``state`` events travel through the queue: every robot process publishing
there (`atemr.ui.publisher.StatePublisher`, or a robot's own dashboard) reaches the ``operators`` of
every dashboard worker on it, each state carrying its robot's name (``robot``).
"""

from __future__ import annotations

import base64
import functools
import logging
import sqlite3
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any, cast

from flask import Flask, current_app, request
from flask_socketio import SocketIO, join_room, leave_room

from atemr.errors import AtemrError, ProtocolError
from atemr.ui.gateway import NO_ROBOT, CommandResult, RobotGateway
from atemr.ui.permissions import Permission, Role
from atemr.ui.screens import ScreenStore
from atemr.ui.security import SCREEN_ONLY, current_screen, current_user, may, refusal, screen_token, session_token
from atemr.ui.users import UserStore

log = logging.getLogger(__name__)

OPERATORS = "operators"
#: Every connected screen (the robot's tablet, with a device token): the robot's state in plain words.
SCREENS = "screens"
CAMERA = "camera"
AGENT = "agent"
#: The ``status`` of an acknowledgement refused for the user's role or permission, as HTTP says it.
FORBIDDEN = 403
#: How often the pushes check that every socket's session is still live (seconds).
REVOKE_CHECK_S = 0.5

Handler = Callable[..., CommandResult | dict[str, Any]]


class Sessions:
    """Which Socket.IO sessions belong to which user, and who watches the camera. Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_sid: dict[str, tuple[str, str]] = {}  # sid → (username, session token)
        self._screens: dict[str, tuple[str, str]] = {}  # sid → (screen name, device token)
        self.camera: set[str] = set()
        self.agent: set[str] = set()
        self.checked_at = -float("inf")  # monotonic time of the last revocation check

    def add(self, sid: str, username: str, token: str) -> None:
        with self._lock:
            self._by_sid[sid] = (username, token)

    def add_screen(self, sid: str, name: str, token: str) -> None:
        with self._lock:
            self._screens[sid] = (name, token)

    def screens(self) -> dict[str, str]:
        """sid → device token of every connected screen."""
        with self._lock:
            return {sid: tok for sid, (_, tok) in self._screens.items()}

    def remove(self, sid: str) -> None:
        with self._lock:
            self._by_sid.pop(sid, None)
            self._screens.pop(sid, None)
            self.camera.discard(sid)
            self.agent.discard(sid)

    def of(self, username: str) -> list[str]:
        with self._lock:
            return [sid for sid, (name, _) in self._by_sid.items() if name == username]

    def of_token(self, token: str) -> list[str]:
        with self._lock:
            return [sid for sid, (_, tok) in self._by_sid.items() if tok == token]

    def tokens(self) -> dict[str, str]:
        """sid → session token of every socket."""
        with self._lock:
            return {sid: tok for sid, (_, tok) in self._by_sid.items()}

    def __len__(self) -> int:
        with self._lock:
            return len(self._by_sid) + len(self._screens)


def socketio_of(app: Flask) -> SocketIO:
    return cast(SocketIO, app.extensions["socketio"])


def sessions_of(app: Flask) -> Sessions:
    return cast(Sessions, app.extensions["atemr.sockets"])


def gateway() -> RobotGateway | None:
    return cast("RobotGateway | None", current_app.extensions["atemr.gateway"])


class EventGroup:
    """A page group's Socket.IO events, handed to `create_app` as its blueprint is (no import side effect,
    no module-global registry): ``events = EventGroup("control")``, then ``@events.on("joystick")``."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.handlers: dict[str, Acknowledge] = {}

    def on(
        self, event: str, role: Role = "user", *, permission: Permission | None = None
    ) -> Callable[[Handler], Handler]:
        """Declare ``event``. The handler gets the robot gateway (or the event is refused when there is none)
        and the event's payload; its return value is the acknowledgement ``{"ok": bool, "reason": str, ...}``.
        The user's role is re-read on every event; an event that does a destructive or safety action names
        its ``permission``, checked the same way."""

        def decorate(handler: Handler) -> Handler:
            if event in self.handlers:
                raise ValueError(f"Socket.IO event {event!r} is declared twice in the {self.name} group")
            self.handlers[event] = _checked(event, role, permission, handler)
            return handler

        return decorate

    def on_screen(self, event: str) -> Callable[[Handler], Handler]:
        """Declare ``event`` as one only the robot's screen sends: its device token is re-checked on every
        event (a revoked token is refused), and an operator's session is refused, so no one poses as the
        screen. The handler gets the robot gateway (None without a robot) and the payload."""

        def decorate(handler: Handler) -> Handler:
            if event in self.handlers:
                raise ValueError(f"Socket.IO event {event!r} is declared twice in the {self.name} group")
            self.handlers[event] = _screen_checked(event, handler)
            return handler

        return decorate

    def register(self, socketio: SocketIO) -> None:
        for event, handler in self.handlers.items():
            socketio.on_event(event, handler)


Acknowledge = Callable[[Any], dict[str, Any]]


def _checked(event: str, role: Role, permission: Permission | None, handler: Handler) -> Acknowledge:
    """``handler`` behind the role and permission checks, its result or refusal as the acknowledgement."""

    @functools.wraps(handler)
    def checked(data: Any = None) -> dict[str, Any]:
        user = current_user()
        if user is None and current_screen() is not None:
            log.warning("socket event %r refused for the screen %s", event, current_screen())
            return {**CommandResult.refused(f"'{event}': {SCREEN_ONLY}").to_json(), "status": FORBIDDEN}
        if user is None or not user.can(role):
            log.warning("socket event %r refused for %s", event, user.username if user else "anonymous")
            return {**CommandResult.refused(f"'{event}' needs the {role} role").to_json(), "status": FORBIDDEN}
        if permission is not None and not may(permission):
            log.warning("socket event %r refused for %s: needs the permission %r", event, user.username, permission)
            return {**CommandResult.refused(refusal(permission)).to_json(), "status": FORBIDDEN}
        robot = gateway()
        if robot is None:
            return NO_ROBOT.to_json()
        try:
            result = handler(robot, data)
        except ProtocolError as exc:
            reason = str(exc)
            log.warning("socket event %r from %s refused: %s", event, user.username,
                        reason if len(reason) <= 300 else reason[:300] + "...")
            return CommandResult.refused(str(exc)).to_json()
        except AtemrError as exc:
            return CommandResult.refused(str(exc)).to_json()
        return result.to_json() if isinstance(result, CommandResult) else result

    return checked


def _screen_checked(event: str, handler: Handler) -> Acknowledge:
    """``handler`` for the screen's session only, its result or refusal as the acknowledgement."""

    @functools.wraps(handler)
    def checked(data: Any = None) -> dict[str, Any]:
        screen = current_screen()
        if screen is None:
            user = current_user()
            log.warning("screen event %r refused for %s", event, user.username if user else "anonymous")
            return {**CommandResult.refused(f"only the robot's screen (with its device token) sends '{event}'")
                    .to_json(), "status": FORBIDDEN}
        try:
            result = handler(gateway(), data)
        except AtemrError as exc:
            log.warning("screen event %r from %s refused: %s", event, screen, str(exc)[:300])
            return CommandResult.refused(str(exc)).to_json()
        return result.to_json() if isinstance(result, CommandResult) else result

    return checked


def _connect(auth: Any = None) -> bool:
    user = current_user()
    token = session_token()
    sid = cast(str, request.sid)  # type: ignore[attr-defined]
    if user is None and (screen := current_screen()) is not None:
        sessions_of(current_app).add_screen(sid, screen, cast(str, screen_token()))
        join_room(SCREENS)
        return True
    if user is None or token is None or not user.can("user"):
        log.info("socket connection refused from %s: no session with access", request.remote_addr)
        return False
    sessions_of(current_app).add(sid, user.username, token)
    join_room(OPERATORS)
    return True


def _disconnect(reason: Any = None) -> None:
    sid = cast(str, request.sid)  # type: ignore[attr-defined]
    sessions_of(current_app).remove(sid)
    for hook in disconnect_hooks(current_app):
        hook(sid)


def disconnect_hooks(app: Flask) -> list[Callable[[str], None]]:
    """What runs when a socket goes (by itself or closed by the server), with its sid: the call ends there."""
    return cast("list[Callable[[str], None]]", app.extensions["atemr.disconnect_hooks"])


def _subscription(event: str, room: str, members: Callable[[Sessions], set[str]]) -> Callable[[Any], dict[str, Any]]:
    """An ``{on: bool}`` event that joins or leaves ``room`` (camera frames, agent view)."""

    def handler(data: Any = None) -> dict[str, Any]:
        user = current_user()
        if user is None or not user.can("user"):
            return CommandResult.refused(f"'{event}' needs the user role").to_json()
        sid = cast(str, request.sid)  # type: ignore[attr-defined]
        on = isinstance(data, dict) and data.get("on") is True
        sessions = sessions_of(current_app)
        try:
            if on:
                join_room(room)
                members(sessions).add(sid)
            else:
                leave_room(room)
                members(sessions).discard(sid)
        except (ValueError, KeyError):  # the client left (page closed) while its event was still queued
            members(sessions).discard(sid)
            return CommandResult.refused("disconnected").to_json()
        return {"ok": True, "reason": "", "on": on}

    return handler


def init_app(app: Flask, socketio: SocketIO, groups: Iterable[EventGroup]) -> None:
    """Attach the connect check, the subscriptions and the page ``groups``' events to ``socketio``."""
    app.extensions["atemr.sockets"] = Sessions()
    app.extensions.setdefault("atemr.disconnect_hooks", [])
    socketio.on_event("connect", _connect)
    socketio.on_event("disconnect", _disconnect)
    socketio.on_event("camera", _subscription("camera", CAMERA, lambda s: s.camera))
    socketio.on_event("agent_view", _subscription("agent_view", AGENT, lambda s: s.agent))
    for group in groups:
        group.register(socketio)


def _close(app: Flask, sids: list[str]) -> None:
    socketio = socketio_of(app)
    for sid in sids:
        socketio.server.disconnect(sid, namespace="/")
        sessions_of(app).remove(sid)
        for hook in disconnect_hooks(app):
            hook(sid)


def disconnect_all(app: Flask) -> None:
    """Close every connection, the robot's screens' too: the server is shutting down, and a page must not stay
    "online" on a connection nothing serves any more. The transports are closed, not only the sockets' namespace
    (a client told "disconnected" over a transport that stays open waits there for good): each page sees its
    connection drop and tries again until a server answers, as after the robot's process ended. The sockets'
    disconnect handler (`_disconnect`) runs for each. Nothing is waited for: engine.io's own ``disconnect()`` waits
    until each socket's queue is sent, which a client that stopped reading holds up for good (the robot's
    shutdown hung on it)."""
    eio = socketio_of(app).server.eio
    for connection in list(eio.sockets.values()):
        connection.close(wait=False, reason=eio.reason.SERVER_DISCONNECT)


def disconnect_user(app: Flask, username: str) -> None:
    """Close every socket of ``username`` (after a password change, a role change or removal)."""
    _close(app, sessions_of(app).of(username))


def disconnect_session(app: Flask, token: str) -> None:
    """Close the sockets of one session (after its logout)."""
    _close(app, sessions_of(app).of_token(token))


def disconnect_revoked(app: Flask) -> int:
    """Close every socket whose session is no longer live in the users database (logged out, expired,
    revoked elsewhere, user removed or without access); returns how many were closed."""
    by_sid = sessions_of(app).tokens()
    screens = sessions_of(app).screens()
    revoked: list[str] = []
    if by_sid:
        store = cast(UserStore, app.extensions["atemr.users"])
        live = store.live_sessions(set(by_sid.values()))
        revoked += [sid for sid, token in by_sid.items() if token not in live]
    if screens:
        live_screens = cast(ScreenStore, app.extensions["atemr.screens"]).live(set(screens.values()))
        revoked += [sid for sid, token in screens.items() if token not in live_screens]
    if revoked:
        log.info("closing %d socket(s) whose session ended", len(revoked))
        _close(app, revoked)
    return len(revoked)


def state_message(robot: RobotGateway) -> dict[str, Any]:
    """The ``state`` event's payload: the robot's snapshot stamped with the wall-clock time it is sent
    (``sent_unix_s``, for latency on the receiving side). A robot-side bug becomes an ``error`` the page
    shows instead of stopping the pushes."""
    try:
        state = dict(robot.state())
    except Exception:  # the dashboard must outlive a robot-side bug; say so on the page
        log.exception("gateway.state() failed")
        state = {"error": "the robot's state could not be read"}
    state["sent_unix_s"] = round(time.time(), 4)
    return state


def screen_message(state: dict[str, Any]) -> dict[str, Any]:
    """What the robot's screen shows of the state: the robot's name, what it does and its charge, in plain
    words (never the map, the pose or the camera: the screen sees only what the resident should read); the
    battery's level too, for the colour."""
    from atemr.ui.screen.words import plain_activity, plain_battery

    battery = state.get("battery")
    level = battery.get("level") if isinstance(battery, dict) else None
    return {"robot": state.get("robot") or "", "words": plain_activity(state), "battery": plain_battery(state),
            "battery_level": level if isinstance(level, str) else ""}


def push(app: Flask, robot: RobotGateway | None) -> int:
    """Send the state snapshot to the operators and a camera frame to the camera watchers.

    Returns the number of clients connected to this worker. Without a message queue nothing is read from
    the robot when nobody watches; with one the state always goes into the queue (other workers' clients
    may watch), while camera frames and the agent view stay with this worker's own watchers (they
    belong to this robot, and frames are too heavy for the queue).
    """
    sessions = sessions_of(app)
    now = time.monotonic()
    if now - sessions.checked_at >= REVOKE_CHECK_S:
        sessions.checked_at = now
        try:
            disconnect_revoked(app)
        except (sqlite3.Error, OSError) as exc:  # a busy or unreadable database must not stop the pushes
            log.warning("cannot check the sockets' sessions: %s", exc)
    clients = len(sessions)
    queued = app.config["ATEMR_CONFIG"].ui.message_queue is not None
    if robot is None or (clients == 0 and not queued):
        return clients
    socketio = socketio_of(app)
    state = state_message(robot)
    socketio.emit("state", state, to=OPERATORS)
    if sessions.screens():
        socketio.emit("screen_state", screen_message(state), to=SCREENS, ignore_queue=True)
    if sessions.camera:
        frame = robot.camera_jpeg()
        if frame:
            socketio.emit("camera", {"jpeg": base64.b64encode(frame).decode("ascii")}, to=CAMERA,
                          ignore_queue=True)
    if sessions.agent:
        try:
            agent = robot.agent_snapshot()
        except Exception:
            log.exception("gateway.agent_snapshot() failed")
            agent = {"error": "the agent's state could not be read"}
        socketio.emit("agent", agent, to=AGENT, ignore_queue=True)
    return clients
