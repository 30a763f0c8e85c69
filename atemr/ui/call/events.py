"""The call's Socket.IO events: the operator rings, mutes nothing here (that stays in the browser), signals
and hangs up; the screen answers, declines, signals and hangs up. The rules live in the pure
`atemr.ui.call.machine.CallMachine`; this module holds the robot's one machine under a lock, checks the
payloads and sends what the machine says.

Signals (``call_signal`` from the operator, ``screen_signal`` from the screen) carry one of
``{"description": {"type": "offer"|"answer", "sdp": str}}`` or ``{"candidate": {...} | null}`` (an ICE
candidate as the browser gives it; null: no more candidates); anything else is refused with the field
named. The ICE servers (``ui.ice_servers``, with ``ui.ice_username``/``ui.ice_credential`` for TURN) reach
both pages in the ``active`` state message, so both ends use the same configuration.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import logging
import threading
import time
from collections.abc import Callable
from typing import Any, cast

from flask import Flask, current_app, request

from atemr.errors import ProtocolError
from atemr.ui.call.machine import STATE_EVENT, CallMachine, Outcome
from atemr.ui.gateway import RobotGateway
from atemr.ui.security import current_user
from atemr.ui.sockets import EventGroup, Handler, disconnect_hooks, sessions_of, socketio_of

log = logging.getLogger(__name__)
events = EventGroup("call")

#: Largest SDP accepted (a two-track offer is a few kB; the socket's buffer is 1 MB).
MAX_SDP_CHARS = 100_000
MAX_CANDIDATE_CHARS = 2_000


class Call:
    """The robot's one call: the machine, its lock, and the app to send through."""

    def __init__(self, app: Flask) -> None:
        self.app = app
        self.machine = CallMachine()
        self.lock = threading.Lock()

    def send(self, outcome: Outcome) -> dict[str, Any]:
        """Send the outcome's messages (the ICE servers added to ``active``) and make the acknowledgement."""
        socketio = socketio_of(self.app)
        for message in outcome.sends:
            data = message.data
            if message.event == STATE_EVENT and data.get("state") == "active":
                data = {**data, "ice_servers": ice_servers(self.app)}
            socketio.emit(message.event, data, to=message.to, ignore_queue=True)
        return {"ok": outcome.ok, "reason": outcome.reason}

    def left(self, sid: str) -> None:
        with self.lock:
            outcome = self.machine.left(sid)
        self.send(outcome)


def ice_servers(app: Flask, now_unix_s: float | None = None) -> list[dict[str, Any]]:
    """The RTCPeerConnection ``iceServers`` from the configuration (empty: host candidates only, a LAN).

    With ``ui.ice_secret`` each answer carries credentials of its own that expire (`turn_credentials`), so a
    page's copy is worth nothing after ``ui.ice_credential_ttl_s``; otherwise the fixed account."""
    config = app.config["ATEMR_CONFIG"]
    ui = config.ui
    account: tuple[str, str] | None = None
    if ui.ice_secret is not None:
        now = time.time() if now_unix_s is None else now_unix_s  # the TURN server checks against its wall clock
        account = turn_credentials(ui.ice_secret, config.secondary.robot_name, now + ui.ice_credential_ttl_s)
    elif ui.ice_username:
        account = (ui.ice_username, ui.ice_credential or "")
    servers: list[dict[str, Any]] = []
    for url in ui.ice_servers:
        server: dict[str, Any] = {"urls": url}
        if url.startswith(("turn:", "turns:")) and account is not None:
            server["username"], server["credential"] = account
        servers.append(server)
    return servers


def turn_credentials(secret: str, user: str, expires_unix_s: float) -> tuple[str, str]:
    """Time-limited TURN credentials from the server's shared secret (the TURN REST API that coturn's
    ``use-auth-secret`` implements): the username is ``EXPIRY:USER`` and the password the base64 HMAC-SHA1
    of that username under the secret, which the TURN server recomputes; it refuses the pair after EXPIRY."""
    username = f"{int(expires_unix_s)}:{user}"
    digest = hmac.new(secret.encode(), username.encode(), hashlib.sha1).digest()
    return username, base64.b64encode(digest).decode("ascii")


def call_of(app: Flask) -> Call:
    return cast(Call, app.extensions["atemr.call"])


def init_app(app: Flask) -> None:
    """Give ``app`` its call; a socket that goes ends the call it was in."""
    call = Call(app)
    app.extensions["atemr.call"] = call
    disconnect_hooks(app).append(call.left)


def _sid() -> str:
    return cast(str, request.sid)  # type: ignore[attr-defined]


def check_signal(event: str, data: Any) -> dict[str, Any]:
    """``data`` if it is one session description or one ICE candidate; else `ProtocolError` naming why."""
    if not isinstance(data, dict) or len(data) != 1 or not ({"description", "candidate"} & data.keys()):
        raise ProtocolError(f"{event}: expected {{description: ...}} or {{candidate: ...}}")
    if "description" in data:
        desc = data["description"]
        if (not isinstance(desc, dict) or desc.get("type") not in ("offer", "answer")
                or not isinstance(desc.get("sdp"), str) or len(desc) != 2):
            raise ProtocolError(f"{event}: description must be {{type: offer|answer, sdp: text}}")
        if len(desc["sdp"]) > MAX_SDP_CHARS:
            raise ProtocolError(f"{event}: the SDP is longer than {MAX_SDP_CHARS} characters")
        return {"description": {"type": desc["type"], "sdp": desc["sdp"]}}
    cand = data["candidate"]
    if cand is None:
        return {"candidate": None}
    if not isinstance(cand, dict) or not isinstance(cand.get("candidate"), str):
        raise ProtocolError(f"{event}: candidate must be {{candidate: text, sdpMid, sdpMLineIndex}} or null")
    if len(cand["candidate"]) > MAX_CANDIDATE_CHARS:
        raise ProtocolError(f"{event}: the candidate is longer than {MAX_CANDIDATE_CHARS} characters")
    mid, index = cand.get("sdpMid"), cand.get("sdpMLineIndex")
    if not (mid is None or (isinstance(mid, str) and len(mid) <= 64)):
        raise ProtocolError(f"{event}: sdpMid must be text or null")
    if not (index is None or (isinstance(index, int) and not isinstance(index, bool) and 0 <= index < 64)):
        raise ProtocolError(f"{event}: sdpMLineIndex must be a small whole number or null")
    return {"candidate": {"candidate": cand["candidate"], "sdpMid": mid, "sdpMLineIndex": index}}


def _no_payload(event: str, data: Any) -> None:
    if data not in (None, {}):
        raise ProtocolError(f"{event}: takes no payload")


# -- the operator ------------------------------------------------------------------------------------------
@events.on("call_start")
def call_start(robot: RobotGateway, data: Any) -> dict[str, Any]:
    """Ring the robot's screen (refused while another call rings or runs, or with no screen connected)."""
    _no_payload("call_start", data)
    app = current_app._get_current_object()  # type: ignore[attr-defined]
    call = call_of(app)
    user = current_user()
    assert user is not None  # the group's check let only a user through
    screens = sorted(sessions_of(app).screens())
    with call.lock:
        outcome = call.machine.ring(_sid(), user.username, screens,
                                    auto_answer=app.config["ATEMR_CONFIG"].ui.screen_auto_answer)
    return call.send(outcome)


def _step(event: str, act: Callable[[CallMachine, str], Outcome]) -> dict[str, Any]:
    """Feed this socket's ``event`` to the machine and send what it says."""
    call = call_of(current_app)
    with call.lock:
        outcome = act(call.machine, _sid())
    log.debug("%s from %s: %s", event, _sid(), outcome.reason or "ok")
    return call.send(outcome)


def _signal(event: str) -> Handler:
    def handler(robot: RobotGateway | None, data: Any) -> dict[str, Any]:
        signal = check_signal(event, data)
        return _step(event, lambda machine, sid: machine.relay(sid, signal))

    return handler


def _bare(event: str, act: Callable[[CallMachine, str], Outcome]) -> Handler:
    def handler(robot: RobotGateway | None, data: Any) -> dict[str, Any]:
        _no_payload(event, data)
        return _step(event, act)

    return handler


events.on("call_signal")(_signal("call_signal"))
events.on("call_end")(_bare("call_end", CallMachine.hang_up))

# -- the robot's screen --------------------------------------------------------------------------------------
events.on_screen("screen_answer")(_bare("screen_answer", CallMachine.answer))
events.on_screen("screen_decline")(_bare("screen_decline", CallMachine.decline))
events.on_screen("screen_signal")(_signal("screen_signal"))
events.on_screen("screen_hangup")(_bare("screen_hangup", CallMachine.hang_up))
