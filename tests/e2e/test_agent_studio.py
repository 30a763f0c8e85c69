"""The Agent studio in Debian's chromium: the live view follows a mission through EXEC and back to IDLE (tree,
blackboard with writers), and a recorded trace replays: seek, step, play, the map at the recorded pose,
search and collapse."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from atemr.io.recording.agent_trace import record_entry
from atemr.io.recording.mcap_writer import RecordingWriter
from atemr.io.trace_file import TraceWriter

pytestmark = pytest.mark.e2e


def wait_for(page, js: str, timeout: float = 8000) -> None:
    """Poll ``js`` until true (``page.wait_for_function`` uses eval, which the dashboard's CSP forbids)."""
    step_ms = 50
    for _ in range(int(timeout / step_ms)):
        if page.evaluate(js):
            return
        page.wait_for_timeout(step_ms)
    raise AssertionError(f"still false after {timeout / 1000:.0f} s: {js}")


def seek(page, t: float) -> None:
    page.evaluate(f"(() => {{ const s = document.getElementById('replay-seek'); s.value = {t}; "
                  "s.dispatchEvent(new Event('input')); })()")


def bb_row(page, key: str) -> list[str]:
    return page.evaluate(f"[...document.querySelectorAll('#agent-blackboard tr')].filter((r) => "
                         f"r.dataset.key === {json.dumps(key)}).map((r) => [...r.children].map((c) => "
                         "c.textContent))[0] || []")


def test_live_view_follows_a_mission_through_exec_and_back_then_replays_it(fast_robot_site, page, shots, helpers):
    site = fast_robot_site
    helpers.login(page, site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{site.url}/agent")
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('agent-current').textContent === 'IDLE.MANUAL'")
    page.evaluate("window.seen = []; ATEMR.socket.on('agent', (s) => { if (window.seen.at(-1) !== s.state) "
                  "window.seen.push(s.state); })")
    assert bb_row(page, "/agent/state")[1:3] == ['"IDLE.MANUAL"', "agent/agent"]
    wait_for(page, "ATEMR.state.level2 && Object.values(ATEMR.state.level2).every((ok) => ok)", timeout=15000)
    assert site.gateway.set_mode("AUTO").ok
    wait_for(page, "document.getElementById('agent-current').textContent === 'IDLE.AUTO'")
    assert site.gateway.start_mission("look-around").ok
    wait_for(page, "document.getElementById('agent-current').textContent === 'EXEC'")
    wait_for(page, "[...document.querySelectorAll('#agent-tree li.node > .name')].some((n) => "
                   "n.textContent.includes('look-around'))")
    wait_for(page, "document.querySelector('#agent-tree li.node.running') !== null")
    assert bb_row(page, "/agent/state")[1:3] == ['"EXEC"', "agent/agent"]
    assert bb_row(page, "/agent/task")[1] == '"look-around"'
    page.screenshot(path=str(shots / "agent-live-exec.png"), full_page=True)
    wait_for(page, "document.getElementById('agent-current').textContent === 'IDLE.AUTO'", timeout=30000)
    seen = page.evaluate("window.seen")
    assert seen[seen.index("EXEC") - 1:][:2] == ["IDLE.AUTO", "EXEC"] and seen[-1] == "IDLE.AUTO"
    assert "reached" in page.inner_text("#agent-transitions")
    assert site.robot.parts.trace.error is None
    # The run was recorded: replay it and seek into EXEC.
    site.robot.parts.trace.flush()
    page.reload()
    wait_for(page, "document.querySelectorAll('#trace-select option').length === 1 && "
                   "document.getElementById('trace-select').value.startsWith('run-')")
    page.click("#trace-open")
    wait_for(page, "document.getElementById('agent-source').textContent.startsWith('REPLAY run-')")
    wait_for(page, "document.getElementById('agent-current').textContent === 'STARTUP'")
    summary = page.evaluate("ATEMR.agentView.replay.summary")
    start = next(t["t"] for t in summary["transitions"] if t["trigger"] == "start_mission")
    seek(page, start + 1.0)
    wait_for(page, "document.getElementById('agent-current').textContent === 'EXEC'")
    assert "look-around" in page.inner_text("#agent-tree")
    assert page.inner_text("#agent-mission") == "look-around (recorded)"
    assert page.evaluate("ATEMR.map.state.pose !== null")
    page.screenshot(path=str(shots / "agent-replay-real.png"), full_page=True)


TREE_NODES = [["exec", "Sequence", -1], ["mission look-around", "Sequence", 0], ["capture look-0", "CaptureImage", 1],
              ["rotate 90", "Rotate", 1], ["report", "Leaf", 0]]
RECORDS = [
    {"k": "head", "t": 10.0, "v": 1, "agent": "agent", "meta": {"map": "room"},
     "machine": {"states": ["STARTUP", "IDLE", "EXEC"], "transitions": []}},
    {"k": "snap", "t": 10.0, "state": "IDLE.AUTO", "mode": "AUTO", "transitions": [],
     "blackboard": {"/agent/state": {"value": "IDLE.AUTO", "by": "agent/agent", "t": 9.0}}},
    {"k": "tree", "t": 10.0, "slot": "tree", "id": 1, "nodes": [["auto", "Sequence", -1], ["Wait", "Leaf", 0]]},
    {"k": "st", "t": 10.0, "id": 1, "n": [[0, "RUNNING", 5, ""], [1, "RUNNING", 5, ""]]},
    {"k": "pose", "t": 10.0, "x": 1.0, "y": 1.0, "yaw": 0.0},
    {"k": "tr", "t": 11.0, "trigger": "start_mission", "source": "IDLE.AUTO", "dest": "EXEC", "accepted": True,
     "reason": "", "origin": "dashboard"},
    {"k": "tree", "t": 11.0, "slot": "tree", "id": 2, "nodes": TREE_NODES},
    {"k": "bb", "t": 11.0, "key": "/agent/state", "value": "EXEC", "by": "agent/agent"},
    {"k": "bb", "t": 11.0, "key": "/mission/step", "value": 0, "by": "mission/look-around"},
    {"k": "st", "t": 11.1, "id": 2, "n": [[0, "RUNNING", 1, ""], [1, "RUNNING", 1, ""], [2, "SUCCESS", 1, "saved"],
                                          [3, "RUNNING", 1, "turning"]]},
    {"k": "pose", "t": 11.5, "x": 2.0, "y": 1.5, "yaw": 0.5},
    {"k": "st", "t": 12.0, "id": 2, "n": [[3, "SUCCESS", 9, "turned"], [4, "RUNNING", 1, ""]]},
    {"k": "bb", "t": 12.0, "key": "/mission/step", "value": 1, "by": "mission/look-around"},
    {"k": "pose", "t": 12.5, "x": 3.0, "y": 2.0, "yaw": 1.0},
    {"k": "tr", "t": 13.0, "trigger": "reached", "source": "EXEC", "dest": "IDLE.AUTO", "accepted": True,
     "reason": "execute succeeded", "origin": "tree:EXEC"},
    {"k": "tree", "t": 13.0, "slot": "tree", "id": 3, "nodes": [["auto", "Sequence", -1], ["Wait", "Leaf", 0]]},
    {"k": "bb", "t": 13.0, "key": "/agent/state", "value": "IDLE.AUTO", "by": "agent/agent"},
    {"k": "pose", "t": 13.5, "x": 3.1, "y": 2.0, "yaw": 1.0},
]


def write_trace(folder: Path, name: str = "mission.mcap") -> Path:
    """The records as the robot records them (MCAP), or as an older ``.atrace`` trace."""
    folder.mkdir(parents=True, exist_ok=True)
    if name.endswith(".mcap"):
        with RecordingWriter(folder / name) as mcap:
            for record in RECORDS:
                mcap.write(*record_entry(record))
        return folder / name
    with TraceWriter(folder / name) as writer:
        for record in RECORDS:
            writer.write(record)
    return folder / name


def statuses(page) -> dict[str, str]:
    return page.evaluate("Object.fromEntries([...document.querySelectorAll('#agent-tree li.node')].map((li) => "
                         "[li.querySelector(':scope > .name').textContent, li.querySelector(':scope > .status')"
                         ".textContent]))")


def visible_nodes(page) -> list[str]:
    return page.evaluate("[...document.querySelectorAll('#agent-tree li.node > .name')].filter((n) => "
                         "n.offsetParent !== null).map((n) => n.textContent)")


def test_a_trace_replays_seek_step_play_search_and_collapse(ready_site, page, shots, helpers):
    write_trace(ready_site.data_dir / "traces")
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{ready_site.url}/agent")
    wait_for(page, "document.getElementById('trace-select').value === 'mission.mcap'")
    page.click("#trace-open")
    wait_for(page, "document.getElementById('replay-time').textContent === '10.0'")
    assert page.inner_text("#agent-current") == "IDLE.AUTO" and page.inner_text("#replay-end") == "13.5"
    assert page.evaluate("ATEMR.map.state.pose.x_m") == 1.0
    # seek into the middle of the mission
    seek(page, 11.7)
    wait_for(page, "document.getElementById('replay-time').textContent === '11.7'")
    assert page.inner_text("#agent-current") == "EXEC"
    assert page.inner_text("#agent-mission") == "no task (recorded)"
    assert statuses(page) == {"exec": "RUNNING", "mission look-around": "RUNNING", "capture look-0": "SUCCESS",
                              "rotate 90": "RUNNING", "report": "INVALID"}
    assert bb_row(page, "/mission/step") == ["/mission/step", "0", "mission/look-around", "11.0"]
    assert page.evaluate("[ATEMR.map.state.pose.x_m, ATEMR.map.state.pose.y_m]") == [2.0, 1.5]
    page.screenshot(path=str(shots / "agent-replay.png"), full_page=True)
    # step to the next change, and back
    page.click("#replay-step")
    wait_for(page, "document.getElementById('replay-time').textContent === '12.0'")
    assert statuses(page)["rotate 90"] == "SUCCESS" and statuses(page)["report"] == "RUNNING"
    assert bb_row(page, "/mission/step")[1] == "1"
    page.click("#replay-back")
    wait_for(page, "document.getElementById('replay-time').textContent === '11.1'")
    assert statuses(page)["rotate 90"] == "RUNNING"
    # search: matching nodes and their ancestors only, blackboard rows filtered too
    page.fill("#agent-search", "rotate")
    wait_for(page, "document.querySelectorAll('#agent-tree li.match').length === 1")
    assert visible_nodes(page) == ["exec", "mission look-around", "rotate 90"]
    page.fill("#agent-search", "mission/")
    assert page.evaluate("[...document.querySelectorAll('#agent-blackboard tr')].map((r) => r.dataset.key)") == \
        ["/mission/step"]
    page.fill("#agent-search", "")
    # collapse a subtree, then everything, then expand
    page.click("#agent-tree li.node[data-key='tree:exec/0'] > .toggle")
    assert visible_nodes(page) == ["exec", "mission look-around", "report"]
    page.click("#tree-collapse")
    assert visible_nodes(page) == ["exec"]
    page.click("#tree-expand")
    assert len(visible_nodes(page)) == 5
    # play to the end: back in IDLE.AUTO where the robot stopped
    page.select_option("#replay-speed", "10")
    page.click("#replay-play")
    wait_for(page, "document.getElementById('replay-time').textContent === '13.5'")
    assert page.inner_text("#agent-current") == "IDLE.AUTO" and page.inner_text("#replay-play") == "PLAY"
    assert "execute succeeded" in page.inner_text("#agent-transitions")
    assert page.evaluate("ATEMR.map.state.pose.x_m") == 3.1
    # back to live: the kinematic robot's agent again
    page.click("#replay-live")
    wait_for(page, "document.getElementById('agent-source').textContent === 'LIVE'")
    wait_for(page, "document.getElementById('agent-current').textContent === 'IDLE.MANUAL'")


def test_a_trace_is_uploaded_and_opened(ready_site, page, helpers, tmp_path):
    path = write_trace(tmp_path, "from robot 2.atrace")
    bad = tmp_path / "bad.atrace"
    bad.write_text("not a trace\n")
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{ready_site.url}/agent")
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    page.set_input_files("#trace-file", str(bad))
    page.click("#trace-upload")
    wait_for(page, "document.getElementById('replay-warning').textContent.includes('neither an MCAP recording')")
    page.set_input_files("#trace-file", str(path))
    page.click("#trace-upload")
    wait_for(page, "document.getElementById('agent-source').textContent === 'REPLAY from_robot_2.atrace'")
    wait_for(page, "document.getElementById('agent-current').textContent === 'IDLE.AUTO'")
    assert (ready_site.data_dir / "traces" / "from_robot_2.atrace").read_bytes() == path.read_bytes()
    assert not (ready_site.data_dir / "traces" / "bad.atrace").exists()
