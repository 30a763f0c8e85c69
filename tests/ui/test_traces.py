"""The Agent page's replay API: list the traces, a trace's summary, the frame at a time, uploads (read before
they are stored) and the refusals (no session, no access, bad names, bad files, no CSRF token)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from flask import Flask

from atemr.io.recording.agent_trace import record_entry
from atemr.io.recording.mcap_writer import RecordingWriter
from atemr.io.trace_file import TraceWriter, encode_record

TREE = {"k": "tree", "t": 0.0, "slot": "tree", "id": 1,
        "nodes": [["manual", "Sequence", -1], ["ReadJoystick", "Leaf", 0], ["Drive", "Leaf", 0]]}
RECORDS = [
    {"k": "head", "t": 0.0, "v": 1, "agent": "agent", "meta": {"map": "studio"},
     "machine": {"states": ["IDLE", "EXEC"], "transitions": []}},
    {"k": "snap", "t": 0.0, "state": "IDLE.MANUAL", "mode": "MANUAL", "transitions": [],
     "blackboard": {"/agent/state": {"value": "IDLE.MANUAL", "by": "agent/agent", "t": 0.0}}},
    TREE,
    {"k": "st", "t": 0.0, "id": 1, "n": [[0, "RUNNING", 1, ""], [1, "SUCCESS", 1, ""], [2, "RUNNING", 1, "idle"]]},
    {"k": "pose", "t": 0.5, "x": 1.0, "y": 1.0, "yaw": 0.0},
    {"k": "tr", "t": 1.0, "trigger": "set_auto", "source": "IDLE.MANUAL", "dest": "IDLE.AUTO", "accepted": True,
     "reason": "", "origin": "dashboard"},
    {"k": "bb", "t": 1.0, "key": "/agent/state", "value": "IDLE.AUTO", "by": "agent/agent"},
    {"k": "st", "t": 1.0, "id": 1, "n": [[2, "FAILURE", 11, "stopped"]]},
    {"k": "pose", "t": 1.5, "x": 2.0, "y": 1.5, "yaw": 0.3},
]


def traces_dir(app: Flask) -> Path:
    folder = app.config["ATEMR_CONFIG"].data_dir / "traces"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@pytest.fixture
def recorded(app: Flask) -> Path:
    path = traces_dir(app) / "run-1.atrace"
    with TraceWriter(path) as writer:
        for r in RECORDS:
            writer.write(r)
    return path


def trace_bytes(records: list[dict] = RECORDS) -> bytes:
    return b"ATEMR-TRACE 1\n" + b"".join(encode_record(r) for r in records)


def mcap_bytes(path: Path, records: list[dict] = RECORDS) -> bytes:
    with RecordingWriter(path) as writer:
        for r in records:
            writer.write(*record_entry(r))
    return path.read_bytes()


def test_an_mcap_recording_is_listed_and_replays(app, alice, ui, tmp_path) -> None:
    """MCAP is what the robot records; its agent topics replay as the .atrace records did."""
    mcap_bytes(traces_dir(app) / "run-2.mcap")
    assert [t["name"] for t in alice.get("/api/traces").get_json()["traces"]] == ["run-2.mcap"]
    got = alice.get("/api/traces/run-2.mcap").get_json()
    assert (got["start_t"], got["end_t"], got["records"]) == (0.0, 1.5, len(RECORDS))
    assert alice.get("/api/traces/run-2.mcap/frame?t=2").get_json()["state"] == "IDLE.AUTO"
    response = upload(alice, ui, "robot 3.mcap", mcap_bytes(tmp_path / "up.mcap"))
    assert response.status_code == 201 and response.get_json()["records"] == len(RECORDS)
    frame = alice.get("/api/traces/robot_3.mcap/frame?t=0.6").get_json()
    assert frame["state"] == "IDLE.MANUAL" and frame["pose"]["x_m"] == 1.0
    cut = upload(alice, ui, "cut.mcap", mcap_bytes(tmp_path / "cut.mcap")[:40])
    assert cut.status_code == 400 and "no 'head' record" in cut.get_json()["reason"]


def test_the_traces_are_listed(app, alice, recorded) -> None:
    got = alice.get("/api/traces").get_json()
    assert got["total"] == 1 and got["traces"][0]["name"] == "run-1.atrace"
    assert got["traces"][0]["size_bytes"] == recorded.stat().st_size


def test_a_summary_lists_the_transitions(app, alice, recorded) -> None:
    got = alice.get("/api/traces/run-1.atrace").get_json()
    assert (got["start_t"], got["end_t"], got["records"]) == (0.0, 1.5, len(RECORDS))
    assert [t["trigger"] for t in got["transitions"]] == ["set_auto"] and got["meta"] == {"map": "studio"}


def test_frames_show_the_recorded_moment(app, alice, recorded) -> None:
    before = alice.get("/api/traces/run-1.atrace/frame?t=0.9").get_json()
    assert before["state"] == "IDLE.MANUAL" and before["pose"] == {"x_m": 1.0, "y_m": 1.0, "yaw_rad": 0.0}
    assert [c["status"] for c in before["tree"]["children"]] == ["SUCCESS", "RUNNING"]
    assert before["next_t"] == 1.0 and before["blackboard"]["/agent/state"]["value"] == "IDLE.MANUAL"
    after = alice.get("/api/traces/run-1.atrace/frame?t=1.6").get_json()
    assert after["state"] == "IDLE.AUTO" and after["t"] == 1.5 and after["pose"]["x_m"] == 2.0
    drive = after["tree"]["children"][1]
    assert (drive["status"], drive["ticks"], drive["feedback"]) == ("FAILURE", 11, "stopped")
    assert after["blackboard"]["/agent/state"] == {"value": "IDLE.AUTO", "by": "agent/agent", "t": 1.0}


@pytest.mark.parametrize("query", ["", "?t=abc", "?t=nan", "?t=inf"])
def test_a_frame_needs_a_finite_time(app, alice, recorded, query) -> None:
    response = alice.get(f"/api/traces/run-1.atrace/frame{query}")
    assert response.status_code == 400 and "finite number" in response.get_json()["reason"]


@pytest.mark.parametrize("name", ["missing.atrace", "..%2Fusers.sqlite3", "run-1.yaml", ".atrace"])
def test_unknown_or_unsafe_names_are_404(app, alice, recorded, name) -> None:
    response = alice.get(f"/api/traces/{name}/frame?t=0")
    assert response.status_code == 404  # (a name with a slash matches no route at all)
    assert response.get_json() is None or response.get_json()["ok"] is False


def test_a_damaged_trace_replays_up_to_the_damage(app, alice, recorded) -> None:
    data = recorded.read_bytes()
    recorded.write_bytes(data[:-10])
    got = alice.get("/api/traces/run-1.atrace").get_json()
    assert got["records"] == len(RECORDS) - 1 and "cut short" in got["warnings"][0]
    assert "run-1.atrace: offset" in got["warnings"][0]


def test_a_file_that_is_no_trace_is_422(app, alice) -> None:
    (traces_dir(app) / "junk.atrace").write_text("hello")
    response = alice.get("/api/traces/junk.atrace")
    assert response.status_code == 422
    assert "neither an MCAP recording nor an ATEMR trace" in response.get_json()["reason"]


@pytest.mark.parametrize("path", ["/api/traces", "/api/traces/run-1.atrace", "/api/traces/run-1.atrace/frame?t=1"])
def test_refused_without_a_session_or_without_access(app, recorded, ui, path) -> None:
    anonymous = app.test_client()
    assert anonymous.get(path).status_code == 401
    bob = app.test_client()
    ui.login(bob, "bob", ui.USER_PW)  # role none
    assert bob.get(path).status_code in (401, 403)
    alice = app.test_client()
    ui.login(alice, "alice", ui.USER_PW)
    app.extensions["atemr.users"].set_role("alice", "none")  # revoked: the session ends at once
    assert alice.get(path).status_code == 401


def upload(client, ui, name: str, data: bytes, *, csrf: bool = True):
    headers = {"X-CSRF-Token": ui.csrf_of(client, "/settings")} if csrf else {}
    return client.post("/api/traces", data={"file": (io.BytesIO(data), name)}, headers=headers,
                       content_type="multipart/form-data")


def test_an_uploaded_trace_is_read_then_stored_and_replays(app, alice, ui) -> None:
    response = upload(alice, ui, "from robot 2.atrace", trace_bytes())
    assert response.status_code == 201
    got = response.get_json()
    assert got == {"ok": True, "reason": "", "name": "from_robot_2.atrace", "records": len(RECORDS), "warnings": []}
    assert alice.get("/api/traces/from_robot_2.atrace/frame?t=2").get_json()["state"] == "IDLE.AUTO"
    again = upload(alice, ui, "from_robot_2.atrace", trace_bytes())
    assert again.status_code == 400 and "exists already" in again.get_json()["reason"]


@pytest.mark.parametrize(("name", "data", "why"), [
    ("run.txt", trace_bytes(), "ending in .mcap or .atrace"),
    ("../../etc.atrace", b"hello", "not a valid trace"),
    ("x.atrace", b"hello\n", "neither an MCAP recording nor an ATEMR trace"),
    ("x.atrace", trace_bytes(RECORDS[1:]), "no 'head' record"),
])
def test_bad_uploads_are_refused_and_nothing_is_stored(app, alice, ui, name, data, why) -> None:
    response = upload(alice, ui, name, data)
    assert response.status_code == 400 and why in response.get_json()["reason"]
    assert list(traces_dir(app).iterdir()) == []


def test_uploads_need_the_csrf_token_and_a_user(app, alice, ui) -> None:
    assert upload(alice, ui, "x.atrace", trace_bytes(), csrf=False).status_code == 400
    bob = app.test_client()
    ui.login(bob, "bob", ui.USER_PW)
    assert app.test_client().post("/api/traces").status_code in (400, 401)
    assert list(traces_dir(app).iterdir()) == []


def test_traces_are_media_too(app, alice, recorded) -> None:
    assert "run-1.atrace" in alice.get("/media").get_data(as_text=True)
    response = alice.get("/media/traces/run-1.atrace")
    assert response.data == recorded.read_bytes()
    response.close()
