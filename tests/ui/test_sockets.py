"""Socket.IO: the connect check, every event (accepted, refused by role, refused for a bad payload),
pushes at 10 Hz to logged-in clients only, camera frames to watchers only, same-origin handshakes."""

from __future__ import annotations

import base64
import math

import pytest

from atemr.msgs import Pose2D, Twist
from atemr.ui import sockets


@pytest.fixture
def fresh_app(tmp_path, gateway, clock, ui):
    """As conftest's, but every destructive or safety action is granted to the user role too, so alice can
    send every event here; the default (admin only) is tested in test_permissions.py."""
    from atemr.ui.app import create_app
    from atemr.ui.permissions import PERMISSIONS

    config = ui.make_config(tmp_path, login_max_failures=3, login_lockout_s=60.0, user_permissions=PERMISSIONS)
    return create_app(config, gateway, clock=clock, hash_method=ui.FAST_SCRYPT)


def sio(app, client):
    return app.extensions["socketio"].test_client(app, flask_test_client=client)


def test_connect_refused_without_a_session(app):
    assert not sio(app, app.test_client()).is_connected()


def test_connect_refused_for_a_user_without_access(app, ui):
    client = app.test_client()
    ui.login(client, "bob", ui.USER_PW)  # denied: no session
    assert not sio(app, client).is_connected()


def test_connect_accepted_with_a_session(app, alice):
    ws = sio(app, alice)
    assert ws.is_connected()
    ws.disconnect()


# (event, payload, gateway call expected)
EVENTS = [
    ("joystick", {"linear_mps": 0.3, "angular_radps": -0.5}, ("joystick", (Twist(0.3, -0.5),))),
    ("mode", {"mode": "AUTO"}, ("set_mode", ("AUTO",))),
    ("mode", {"mode": "MANUAL"}, ("set_mode", ("MANUAL",))),
    ("goal", {"x_m": 1.0, "y_m": 2.0, "yaw_rad": 0.5}, ("set_goal", (Pose2D(1.0, 2.0, 0.5),))),
    ("initial_pose", {"x_m": -1.0, "y_m": 0.0, "yaw_rad": 0.0}, ("set_initial_pose", (Pose2D(-1.0, 0.0, 0.0),))),
    ("localize_globally", None, ("localize_globally", ())),
    ("cancel_goal", None, ("cancel_goal", ())),
    ("capture_image", None, ("capture_image", ())),
    ("record_video", {"on": True}, ("record_video", (True,))),
    ("mission_start", {"name": "patrol"}, ("start_mission", ("patrol",))),
    ("mission_stop", None, ("stop_mission", ())),
    ("sim_button", {"hold_s": 1.2}, ("sim_button", (1.2,))),
    ("sim_obstacle", {"x_m": 1.5, "y_m": -0.5}, ("sim_drop_obstacle", (1.5, -0.5))),
    ("sim_kidnap", {"x_m": 3.0, "y_m": 1.0, "yaw_rad": 3.0}, ("sim_kidnap", (Pose2D(3.0, 1.0, 3.0),))),
    ("mapping_begin", None, ("begin_mapping", ())),
    ("mapping_end", None, ("end_mapping", ())),
    ("map_save", {"name": "kitchen"}, ("save_map", ("kitchen",))),
    ("map_discard", None, ("discard_map", ())),
    ("map_select", {"name": "kitchen.yaml"}, ("select_map", ("kitchen",))),
    ("autonomy_confirm", {"id": 3}, ("answer_transition", (3, True, "alice"))),
    ("autonomy_deny", {"id": 4}, ("answer_transition", (4, False, "alice"))),
    ("autonomy_level", {"level": "low"}, ("set_autonomy", ("low", "alice"))),
    ("agent_reload", None, ("reload_agent", ())),
    ("go_to_place", {"name": "kitchen"}, ("go_to_place", ("kitchen",))),
    ("place_save", {"name": "Mum's armchair", "x_m": 1.0, "y_m": 2.0, "yaw_rad": 0.5},
     ("save_place", ("Mum's armchair", Pose2D(1.0, 2.0, 0.5), "place", None))),
    ("place_save", {"name": "hall", "x_m": 1.0, "y_m": 2.0, "yaw_rad": 0, "kind": "dock", "previous": "home"},
     ("save_place", ("hall", Pose2D(1.0, 2.0, 0.0), "dock", "home"))),
    ("place_delete", {"name": "hall"}, ("delete_place", ("hall",))),
]


@pytest.mark.parametrize(("event", "data", "call"), EVENTS, ids=[e[0] + str(i) for i, e in enumerate(EVENTS)])
def test_every_event_reaches_the_gateway(app, alice, gateway, event, data, call):
    ws = sio(app, alice)
    ack = ws.emit(event, data, callback=True)
    assert ack == {"ok": True, "reason": ""}
    assert gateway.calls == [call]
    ws.disconnect()


@pytest.mark.parametrize(("event", "data", "call"), EVENTS, ids=[e[0] + str(i) for i, e in enumerate(EVENTS)])
def test_every_event_passes_on_the_robots_refusal(app, alice, gateway, event, data, call):
    gateway.refuse[call[0]] = "not now"
    ack = sio(app, alice).emit(event, data, callback=True)
    assert ack == {"ok": False, "reason": "not now"}


@pytest.mark.parametrize(("event", "data", "call"), EVENTS, ids=[e[0] + str(i) for i, e in enumerate(EVENTS)])
def test_every_event_rechecks_the_role(app, alice, gateway, event, data, call):
    ws = sio(app, alice)
    app.extensions["atemr.users"].set_role("alice", "none")  # revoked behind the socket's back
    ack = ws.emit(event, data, callback=True)
    assert ack["ok"] is False and ack["status"] == 403 and "needs the user role" in ack["reason"]
    assert gateway.calls == []


BAD = [
    ("joystick", {"linear_mps": math.nan, "angular_radps": 0}),
    ("joystick", {"linear_mps": 9.0, "angular_radps": 0}),
    ("joystick", {"linear_mps": "0.2", "angular_radps": 0}),
    ("joystick", {"linear_mps": True, "angular_radps": 0}),
    ("joystick", [0.2, 0.0]),
    ("joystick", None),
    ("mode", {"mode": "TURBO"}),
    ("goal", {"x_m": 1.0, "y_m": math.inf, "yaw_rad": 0}),
    ("goal", {"x_m": 1.0}),
    ("record_video", {"on": "yes"}),
    ("mission_start", {"name": ""}),
    ("sim_button", {"hold_s": 100}),
    ("map_save", {"name": "../../etc/passwd"}),
    ("map_save", {"name": "a b"}),
    ("map_select", {"name": ".hidden"}),
    ("autonomy_confirm", {"id": "3"}),
    ("autonomy_confirm", {"id": True}),
    ("autonomy_deny", {}),
    ("autonomy_deny", None),
    ("autonomy_level", {"level": "max"}),
    ("autonomy_level", {"level": 2}),
    ("go_to_place", {"name": ""}),
    ("go_to_place", {"name": "x" * 41}),
    ("place_save", {"name": "hall", "x_m": 1.0, "y_m": math.nan, "yaw_rad": 0}),
    ("place_save", {"name": "hall", "x_m": 1.0, "y_m": 2.0}),
    ("place_save", {"name": "hall", "x_m": 1.0, "y_m": 2.0, "yaw_rad": 0, "previous": 7}),
    ("place_delete", {"name": 3}),
]


@pytest.mark.parametrize(("event", "data"), BAD)
def test_bad_payloads_are_refused_with_the_field_named(app, alice, gateway, event, data):
    ack = sio(app, alice).emit(event, data, callback=True)
    assert ack["ok"] is False
    assert event in ack["reason"] or "unknown mode" in ack["reason"]
    assert gateway.calls == []


def test_yaw_is_wrapped(app, alice, gateway):
    sio(app, alice).emit("goal", {"x_m": 0, "y_m": 0, "yaw_rad": 2 * math.pi + 0.25}, callback=True)
    assert gateway.calls[0][1][0].yaw_rad == pytest.approx(0.25)


def test_push_sends_state_to_logged_in_clients_only(app, alice, gateway):
    ws = sio(app, alice)
    other = app.test_client()
    assert not sio(app, other).is_connected()
    gateway.snapshot["agent_state"] = "EXEC"
    assert sockets.push(app, gateway) == 1
    received = [m for m in ws.get_received() if m["name"] == "state"]
    assert received and received[-1]["args"][0]["agent_state"] == "EXEC"
    sent = received[-1]["args"][0]["sent_unix_s"]  # stamped when sent, for the receivers' latency
    assert isinstance(sent, float) and sent > 1.7e9


def test_push_reads_nothing_when_nobody_watches(app, gateway):
    gateway.state = None  # would raise if called
    assert sockets.push(app, gateway) == 0


def test_a_failing_gateway_is_reported_not_fatal(app, alice, gateway):
    ws = sio(app, alice)

    def broken() -> dict:
        raise RuntimeError("robot-side bug")

    gateway.state = broken
    sockets.push(app, gateway)
    state = [m for m in ws.get_received() if m["name"] == "state"][-1]["args"][0]
    assert "could not be read" in state["error"]


def test_camera_frames_only_to_watchers(app, alice, gateway, ui):
    gateway.jpeg = b"\xff\xd8jpeg\xff\xd9"
    watcher = sio(app, alice)
    second = app.test_client()
    ui.login(second, "admin", ui.ADMIN_PW)
    idle = sio(app, second)
    assert watcher.emit("camera", {"on": True}, callback=True)["on"] is True
    sockets.push(app, gateway)
    frames = [m for m in watcher.get_received() if m["name"] == "camera"]
    assert base64.b64decode(frames[-1]["args"][0]["jpeg"]) == gateway.jpeg
    assert not [m for m in idle.get_received() if m["name"] == "camera"]
    watcher.emit("camera", {"on": False}, callback=True)
    sockets.push(app, gateway)
    assert not [m for m in watcher.get_received() if m["name"] == "camera"]


def test_logout_and_role_change_disconnect_the_users_sockets(app, alice, ui):
    ws = sio(app, alice)
    assert ws.is_connected()
    ui.post(alice, "/auth/logout")
    assert not ws.is_connected()
    admin = app.test_client()
    ui.login(admin, "admin", ui.ADMIN_PW)
    carol = app.test_client()
    app.extensions["atemr.users"].create("carol", "carol-pass", "user")
    ui.login(carol, "carol", "carol-pass")
    ws2 = sio(app, carol)
    assert ws2.is_connected()
    ui.post(admin, "/settings/users/carol/role", {"role": "none"})
    assert not ws2.is_connected()


def test_without_a_robot_events_are_refused(tmp_path, ui):
    from atemr.ui.app import create_app

    app = create_app(ui.make_config(tmp_path), None, hash_method=ui.FAST_SCRYPT)
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = app.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    ack = sio(app, client).emit("mode", {"mode": "AUTO"}, callback=True)
    assert ack == {"ok": False, "reason": "no robot is connected to the dashboard"}


def test_cross_origin_handshake_is_refused(app, alice):
    ok = alice.get("/socket.io/?EIO=4&transport=polling", headers={"Origin": "http://localhost"})
    assert ok.status_code == 200
    evil = alice.get("/socket.io/?EIO=4&transport=polling", headers={"Origin": "http://evil.example"})
    assert evil.status_code == 400
    assert app.extensions["socketio"].server.eio.cors_allowed_origins != "*"


AGENT = {"state": "IDLE.MANUAL", "mode": "MANUAL", "valid_triggers": ["goal", "begin_mapping"],
         "tree": {"name": "Idle", "type": "Sequence", "status": "RUNNING", "children": [
             {"name": "Fuzzy", "type": "Leaf", "status": "SUCCESS"}]},
         "transitions": [{"t": 1.0, "trigger": "started", "source": "STARTUP", "dest": "IDLE", "accepted": True,
                          "reason": "all checks passed"}]}


def test_agent_snapshot_only_to_agent_view_subscribers(app, alice, gateway, ui):
    gateway.agent = AGENT
    viewer = sio(app, alice)
    other_client = app.test_client()
    ui.login(other_client, "admin", ui.ADMIN_PW)
    other = sio(app, other_client)
    assert viewer.emit("agent_view", {"on": True}, callback=True)["on"] is True
    sockets.push(app, gateway)
    got = [m["args"][0] for m in viewer.get_received() if m["name"] == "agent"]
    assert got == [AGENT]
    assert not [m for m in other.get_received() if m["name"] == "agent"]
    viewer.emit("agent_view", {"on": False}, callback=True)
    sockets.push(app, gateway)
    assert not [m for m in viewer.get_received() if m["name"] == "agent"]


def test_subscriptions_recheck_the_role(app, alice):
    ws = sio(app, alice)
    app.extensions["atemr.users"].set_role("alice", "none")
    for event in ("camera", "agent_view"):
        ack = ws.emit(event, {"on": True}, callback=True)
        assert ack["ok"] is False and "needs the user role" in ack["reason"]


def test_a_failing_agent_snapshot_is_reported(app, alice, gateway):
    def broken() -> dict:
        raise RuntimeError("agent bug")

    gateway.agent_snapshot = broken
    ws = sio(app, alice)
    ws.emit("agent_view", {"on": True}, callback=True)
    sockets.push(app, gateway)
    got = [m["args"][0] for m in ws.get_received() if m["name"] == "agent"]
    assert "could not be read" in got[-1]["error"]


@pytest.mark.parametrize("event", ["autonomy_confirm", "autonomy_deny", "autonomy_level", "agent_reload"])
def test_studio_events_are_refused_without_a_session_or_a_role(app, gateway, ui, event):
    anonymous = sio(app, app.test_client())
    assert not anonymous.is_connected()
    client = app.test_client()
    ui.login(client, "bob", ui.USER_PW)  # role none
    assert not sio(app, client).is_connected()
    assert gateway.calls == []


def test_page_groups_declare_their_events_once_and_every_event_is_registered(app):
    from atemr.ui.agent.events import events as agent
    from atemr.ui.call.events import events as call
    from atemr.ui.control.events import events as control
    from atemr.ui.drive_video.events import events as drive_video
    from atemr.ui.mapping.events import events as mapping

    declared = (set(control.handlers) | set(mapping.handlers) | set(agent.handlers) | set(call.handlers)
                | set(drive_video.handlers))
    # every declared event is tested above or below (the drive video's in test_drive_video.py), and no other
    assert declared == {e[0] for e in EVENTS} | {e[0] for e in CALL_EVENTS} | {"drive_video_offer", "drive_video_stop"}
    registered = set(app.extensions["socketio"].server.handlers["/"])
    assert declared | {"connect", "disconnect", "camera", "agent_view"} == registered
    group = sockets.EventGroup("test")
    group.on("ping")(lambda robot, data: {"ok": True})
    with pytest.raises(ValueError, match="'ping' is declared twice in the test group"):
        group.on("ping")(lambda robot, data: {"ok": True})


# -- the call (atemr.ui.call): (event, payload, who may send it) -----------------------------------------------
CALL_EVENTS = [
    ("call_start", None, "operator"),
    ("call_signal", {"candidate": None}, "operator"),
    ("call_end", None, "operator"),
    ("screen_answer", None, "screen"),
    ("screen_decline", None, "screen"),
    ("screen_signal", {"candidate": None}, "screen"),
    ("screen_hangup", None, "screen"),
]


def screen_socket(app):
    token = app.extensions["atemr.screens"].add("tablet")
    tablet = app.test_client()
    tablet.get(f"/screen?token={token}")
    return sio(app, tablet)


def call_states(ws):
    return [m["args"][0] for m in ws.get_received() if m["name"] == "call_state"]


@pytest.mark.parametrize(("event", "data", "who"), CALL_EVENTS)
def test_call_events_are_refused_to_the_other_side_and_to_strangers(app, alice, ui, event, data, who):
    wrong = screen_socket(app) if who == "operator" else sio(app, alice)
    ack = wrong.emit(event, data, callback=True)
    assert ack["ok"] is False and ack["status"] == 403, ack
    assert ("screen device token opens only" if who == "operator" else "only the robot's screen") in ack["reason"]
    assert not sio(app, app.test_client()).is_connected()  # no session, no token: not even connected


def test_a_call_through_the_sockets(app, alice, ui, tmp_path):
    screen = screen_socket(app)
    operator = sio(app, alice)
    assert operator.emit("call_start", None, callback=True) == {"ok": True, "reason": ""}
    ringing = call_states(screen)[-1]  # (each read drains what the socket received)
    assert ringing["state"] == "ringing" and ringing["caller"] == "alice"
    carol = app.test_client()
    app.extensions["atemr.users"].create("carol", ui.USER_PW, "user")
    ui.login(carol, "carol", ui.USER_PW)
    second = sio(app, carol)
    refused = second.emit("call_start", None, callback=True)
    assert refused == {"ok": False, "reason": "the robot is ringing with alice: one call at a time"}
    assert screen.emit("screen_answer", None, callback=True)["ok"]
    active = call_states(operator)[-1]
    assert active["state"] == "active" and active["ice_servers"] == []
    offer = {"description": {"type": "offer", "sdp": "v=0 test"}}
    assert operator.emit("call_signal", offer, callback=True)["ok"]
    assert [m["args"][0] for m in screen.get_received() if m["name"] == "call_signal"] == [offer]
    assert not second.emit("call_signal", offer, callback=True)["ok"]  # not a party
    operator.disconnect()  # the page closed
    assert call_states(screen)[-1] == {"state": "idle", "caller": "alice", "role": "", "reason": "the caller left"}
    assert second.emit("call_start", None, callback=True)["ok"]  # free again


@pytest.mark.parametrize("data", [
    {"description": {"type": "pranswer", "sdp": "v=0"}},
    {"description": {"type": "offer", "sdp": "x" * 100_001}},
    {"description": {"type": "offer"}},
    {"candidate": {"candidate": 5}},
    {"candidate": {"candidate": "c", "sdpMLineIndex": True}},
    {"candidate": None, "description": None},
    "offer",
    None,
])
def test_bad_call_signals_are_refused_with_the_event_named(app, alice, data):
    screen = screen_socket(app)
    operator = sio(app, alice)
    operator.emit("call_start", None, callback=True)
    screen.emit("screen_answer", None, callback=True)
    ack = operator.emit("call_signal", data, callback=True)
    assert ack["ok"] is False and "call_signal" in ack["reason"], ack


def test_ice_servers_and_auto_answer_from_the_configuration(tmp_path, gateway, clock, ui):
    from atemr.ui.app import create_app

    config = ui.make_config(tmp_path, screen_auto_answer=True, ice_servers=("stun:stun.example.org:3478",
                            "turn:turn.example.org:3478"), ice_username="kay", ice_credential="s3cret")
    app = create_app(config, gateway, clock=clock, hash_method=ui.FAST_SCRYPT)
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    admin = app.test_client()
    ui.login(admin, "admin", ui.ADMIN_PW)
    screen = screen_socket(app)
    operator = sio(app, admin)
    assert operator.emit("call_start", None, callback=True)["ok"]
    assert call_states(screen)[-1]["ice_servers"] == [
        {"urls": "stun:stun.example.org:3478"},
        {"urls": "turn:turn.example.org:3478", "username": "kay", "credential": "s3cret"}]
    assert call_states(operator)[-1]["state"] == "active"


def test_turn_credentials_from_a_shared_secret_are_made_per_call_and_expire(tmp_path, gateway, clock, ui):
    """coturn's use-auth-secret: the server recomputes HMAC-SHA1(secret, "EXPIRY:USER") and refuses it after
    EXPIRY, so a page keeps nothing that lasts; each call's active message carries a fresh pair."""
    import base64
    import hashlib
    import hmac
    import time

    from atemr.ui.app import create_app
    from atemr.ui.call.events import ice_servers

    config = ui.make_config(tmp_path, ice_servers=("stun:stun.example.org:3478", "turns:turn.example.org:5349"),
                            ice_secret="coturn-static-secret", ice_credential_ttl_s=600.0)
    app = create_app(config, gateway, clock=clock, hash_method=ui.FAST_SCRYPT)
    stun, turn = ice_servers(app, now_unix_s=1_800_000_000.0)
    assert stun == {"urls": "stun:stun.example.org:3478"}
    assert turn["urls"] == "turns:turn.example.org:5349" and turn["username"] == "1800000600:KAY"
    expected = hmac.new(b"coturn-static-secret", b"1800000600:KAY", hashlib.sha1).digest()
    assert base64.b64decode(turn["credential"]) == expected
    assert ice_servers(app, now_unix_s=1_800_000_100.0)[1]["username"] == "1800000700:KAY"
    # on a real call the pages get a pair that expires ttl after now
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    admin = app.test_client()
    ui.login(admin, "admin", ui.ADMIN_PW)
    screen = screen_socket(app)
    operator = sio(app, admin)
    before = time.time()
    assert operator.emit("call_start", None, callback=True)["ok"]
    assert screen.emit("screen_answer", None, callback=True)["ok"]
    sent = call_states(screen)[-1]["ice_servers"][1]
    expiry = int(sent["username"].split(":")[0])
    assert before + 600 - 1 <= expiry <= time.time() + 600
    assert "coturn-static-secret" not in str(call_states(operator))
    # the drive video's answer too: made when asked, not once at start-up
    first = admin.get("/api/drive-video").get_json()["ice_servers"]
    if first:  # WebRTC offered (aiortc installed): its TURN pair is as fresh
        assert before + 600 - 1 <= int(first[1]["username"].split(":")[0]) <= time.time() + 600


@pytest.mark.parametrize(("ui_settings", "message"), [
    ({"ice_servers": ("http://stun.example.org",)}, "must start with stun:"),
    ({"ice_servers": ("turn:turn.example.org",)}, "set ui.ice_secret"),
    ({"ice_secret": "s", "ice_username": "kay", "ice_credential": "c"}, "not both"),
])
def test_bad_ice_settings_are_refused(ui_settings, message, ui, tmp_path):
    from atemr.errors import ConfigError

    with pytest.raises(ConfigError, match=message):
        ui.make_config(tmp_path, **ui_settings)


# -- the drive video (atemr.ui.drive_video; the negotiation itself: test_drive_video.py) -------------------------
DRIVE_VIDEO_EVENTS = [
    ("drive_video_offer", {"description": {"type": "offer", "sdp": "v=0\r\n"}}),
    ("drive_video_stop", None),
]


@pytest.mark.parametrize(("event", "data"), DRIVE_VIDEO_EVENTS)
def test_drive_video_events_are_refused_to_the_robots_screen(app, event, data):
    ack = screen_socket(app).emit(event, data, callback=True)
    assert ack["ok"] is False and ack["status"] == 403, ack
    assert "screen device token opens only" in ack["reason"], ack
