"""Screen device tokens: made once, only the hash stored, listed without tokens, revoked for good; the
screen page and events open with a token only, and a token opens nothing else."""

from __future__ import annotations

import argparse
import sqlite3

import pytest

from atemr.cli.screen import ScreenCommand
from atemr.ui.screen.words import plain_activity, plain_battery
from atemr.ui.screens import ScreenError, ScreenStore, token_hash


def test_add_list_verify_revoke(tmp_path):
    store = ScreenStore(tmp_path / "users.sqlite3")
    token = store.add("tablet")
    assert len(token) >= 40
    assert store.verify(token) == "tablet"
    assert [s.name for s in store.list()] == ["tablet"]
    assert store.live({token, "other"}) == {token}
    store.revoke("tablet")
    assert store.verify(token) is None and store.list() == [] and store.live({token}) == set()
    with pytest.raises(ScreenError, match="no screen called 'tablet'"):
        store.revoke("tablet")


def test_only_the_hash_is_stored(tmp_path):
    path = tmp_path / "users.sqlite3"
    token = ScreenStore(path).add("tablet")
    with sqlite3.connect(path) as db:
        rows = db.execute("SELECT * FROM screens").fetchall()
    assert token not in repr(rows) and token_hash(token) in repr(rows)
    assert path.stat().st_mode & 0o077 == 0


def test_bad_names_and_taken_names_are_refused(tmp_path):
    store = ScreenStore(tmp_path / "users.sqlite3")
    store.add("tablet")
    with pytest.raises(ScreenError, match="exists; revoke it first"):
        store.add("tablet")
    with pytest.raises(ScreenError, match="1 to 32 letters"):
        store.add("../x")
    assert store.verify("") is None and store.verify("x" * 500) is None


def run_cli(tmp_path, *argv):
    parser = argparse.ArgumentParser()
    command = ScreenCommand()
    command.configure(parser)
    return command.run(parser.parse_args(["--data-dir", str(tmp_path), *argv]))


def test_cli_prints_the_token_once_then_lists_and_revokes(tmp_path, capsys):
    assert run_cli(tmp_path, "add", "tablet") == 0
    token = capsys.readouterr().out.strip()
    assert ScreenStore(tmp_path / "users.sqlite3").verify(token) == "tablet"
    assert run_cli(tmp_path, "list") == 0
    listed = capsys.readouterr().out
    assert "tablet" in listed and token not in listed
    assert run_cli(tmp_path, "revoke", "tablet") == 0
    assert ScreenStore(tmp_path / "users.sqlite3").verify(token) is None


def test_screen_page_needs_its_token(app, ui):
    anon = app.test_client()
    response = anon.get("/screen")
    assert response.status_code == 403 and "device token" in response.get_data(as_text=True)
    response = anon.get("/screen?token=forged")
    assert response.status_code == 403 and "unknown or was revoked" in response.get_data(as_text=True)
    operator = app.test_client()
    ui.login(operator, "alice", ui.USER_PW)
    response = operator.get("/screen")
    assert response.status_code == 403 and "cannot pose as the screen" in response.get_data(as_text=True)


def test_a_screen_token_opens_the_screen_and_nothing_else(app):
    token = app.extensions["atemr.screens"].add("tablet")
    tablet = app.test_client()
    response = tablet.get(f"/screen?token={token}")
    assert response.status_code == 302 and response.headers["Location"] == "/screen"  # the token leaves the URL
    page = tablet.get("/screen")
    assert page.status_code == 200 and 'id="answer"' in page.get_data(as_text=True)
    for path in ("/control", "/settings", "/api/state", "/media", "/api/camera.mjpeg"):
        refused = tablet.get(path)
        assert refused.status_code == 403, path
        assert "screen device token opens only" in refused.get_data(as_text=True), path
    app.extensions["atemr.screens"].revoke("tablet")
    assert tablet.get("/screen").status_code == 403


def test_screen_socket_gets_plain_words_and_is_refused_operator_events(app, gateway):
    from atemr.ui import sockets

    token = app.extensions["atemr.screens"].add("tablet")
    tablet = app.test_client()
    tablet.get(f"/screen?token={token}")
    ws = app.extensions["socketio"].test_client(app, flask_test_client=tablet)
    assert ws.is_connected()
    for event, data in (("joystick", {"linear_mps": 0.1, "angular_radps": 0}), ("call_start", None)):
        ack = ws.emit(event, data, callback=True)
        assert ack["ok"] is False and ack["status"] == 403 and "screen device token opens only" in ack["reason"]
    assert gateway.calls == []
    gateway.snapshot["battery"] = {"percent": 17.6, "voltage_v": 25.4, "level": "low"}
    sockets.push(app, gateway)
    words = [m["args"][0] for m in ws.get_received() if m["name"] == "screen_state"]
    assert words and words[-1]["words"] == plain_activity(gateway.state())
    assert words[-1]["battery"] == "Battery low: 18 %" and words[-1]["battery_level"] == "low"
    assert set(words[-1]) == {"robot", "words", "battery", "battery_level"}  # nothing of the map, pose or camera
    app.extensions["atemr.screens"].revoke("tablet")
    app.extensions["atemr.sockets"].checked_at = -1e9
    sockets.push(app, gateway)
    assert not ws.is_connected()


@pytest.mark.parametrize(("state", "words"), [
    ({"stop_cause": "obstacle", "agent_state": "EXEC"}, "Stopped: something in front of me"),
    ({"agent_state": "EXEC", "goal": {"x_m": 1.0}, "mission": None}, "Going to a goal"),
    ({"agent_state": "EXEC", "mission": {"name": "visit_kitchen", "progress": 0.5, "state": "RUNNING"}},
     "Doing the task 'visit_kitchen'"),
    ({"agent_state": "IDLE", "mode": "MANUAL"}, "Waiting; someone can drive me from afar"),
    ({"agent_state": "IDLE", "mode": "MANUAL", "localization": {"state": "ambiguous", "looking_around": True}},
     "Turning to look around: finding where I am"),  # it moves by itself after FIND POSITION: say why
    ({"agent_state": "IDLE", "mode": "MANUAL", "localization": {"state": "ambiguous", "looking_around": False}},
     "Waiting; someone can drive me from afar"),
    ({"agent_state": "MAPPING"}, "Learning the rooms"),
    ({"agent_state": "ERROR"}, "I have stopped: something is wrong"),  # no promise that help is on the way
    ({"emergency": True}, "Stopped: emergency stop"),
    ({}, "Starting up"),
])
def test_plain_activity(state, words):
    assert plain_activity(state) == words


def test_the_token_stays_out_of_the_request_log():
    from atemr.ui.server import hide_tokens

    line = '"GET /screen?token=Abc-_123 HTTP/1.1" 302 -'
    assert hide_tokens(line) == '"GET /screen?token=<hidden> HTTP/1.1" 302 -'
    assert hide_tokens('"GET /screen?a=1&token=x HTTP/1.1"') == '"GET /screen?a=1&token=<hidden> HTTP/1.1"'


@pytest.mark.parametrize(("battery", "words"), [
    ({"percent": 76.4, "voltage_v": 27.1, "level": "ok"}, "Battery 76 %"),
    ({"percent": 18.0, "voltage_v": 25.4, "level": "low"}, "Battery low: 18 %"),
    ({"percent": 9.2, "voltage_v": 24.6, "level": "return"}, "Battery 9 %: I need to charge"),
    ({"percent": 4.0, "voltage_v": 23.0, "level": "critical"}, "Battery 4 %: please put me on my charger"),
    (None, ""),
    ({"percent": "lots"}, ""),
])
def test_plain_battery(battery, words):
    assert plain_battery({"battery": battery}) == words
