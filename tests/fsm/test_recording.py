"""The agent recorder and the timeline: a run on fake ports is recorded, and the timeline's frame at any
recorded moment shows what the live snapshot showed then (state, tree statuses, blackboard with writers)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from atemr.clock import SimClock
from atemr.fsm import trace_timeline
from atemr.fsm.agent import Agent
from atemr.fsm.recording import AgentRecorder
from atemr.fsm.spec import AgentSpec
from atemr.fsm.trace_timeline import CHECKPOINT_EVERY, TraceTimeline
from atemr.io.trace_file import TraceWriter, read_trace
from atemr.msgs import Pose2D
from atemr.scheduler import Scheduler
from atemr.trees.fakes import RecordingLink, RecordingPort, StraightLineNavigation


class Recorded:
    """An agent at 10 Hz on a simulated clock, recorded into ``records`` (and live snapshots kept by time)."""

    def __init__(self, spec: AgentSpec, link: RecordingLink) -> None:
        self.clock = SimClock()
        self.port = RecordingPort(current_pose=Pose2D(2.6, 2.6, 0.0))
        self.navigation = StraightLineNavigation(self.port, speed_mps=1.0)
        self.agent = Agent(spec, self.port, link, navigation=self.navigation)
        link.time_source = self.clock.now
        self.records: list[dict[str, Any]] = []
        self.recorder = AgentRecorder(self.agent, self.records.append, pose_hz=2.0, meta={"world": "fake"})
        self.records.extend(self.recorder.preamble())
        self.recorder.attach()
        self.snapshots: dict[float, dict[str, Any]] = {}
        self.scheduler = Scheduler(self.clock)
        self.scheduler.add(self.agent, 10.0)
        self.scheduler.start()

    def run(self, seconds: float) -> None:
        until = self.clock.now() + seconds
        while self.clock.now() < until - 1e-9:
            self.scheduler.step()
            snap = json.loads(json.dumps(self.agent.snapshot()))
            self.snapshots[round(self.agent.context.now, 3)] = snap

    def command(self, trigger: str, **kwargs: Any) -> None:
        self.agent.submit(trigger, origin="test", **kwargs)
        self.run(0.1)


@pytest.fixture
def recorded(agent_spec: AgentSpec, link: RecordingLink) -> Recorded:
    rec = Recorded(agent_spec, link)
    rec.run(0.5)
    rec.command("set_auto")
    rec.command("goal", goal=Pose2D(3.6, 2.6, 1.0))
    rec.run(2.5)
    assert rec.agent.state == "IDLE.AUTO"
    return rec


def ticks(node: dict[str, Any] | None) -> list[int]:
    return [] if node is None else [node["ticks"], *(t for c in node.get("children", []) for t in ticks(c))]


def shape(node: dict[str, Any] | None) -> Any:
    """Name, status and children of a snapshot tree (what the live view and the replay both draw)."""
    if node is None:
        return None
    return (node["name"], node["status"], [shape(c) for c in node.get("children", [])])


def test_every_transition_is_recorded_with_its_reason(recorded: Recorded) -> None:
    trs = [r for r in recorded.records if r["k"] == "tr"]
    live = [r.as_dict() for r in recorded.agent.trace if r.trigger != "(initial)"]
    assert [(r["t"], r["trigger"], r["dest"], r["reason"], r["origin"]) for r in trs] == \
        [(round(r["t"], 3), r["trigger"], r["dest"], r["reason"], r["origin"]) for r in live]
    timeline = TraceTimeline(recorded.records)
    assert [t["trigger"] for t in timeline.transitions()] == ["(initial)", "startup_ok", "set_auto", "goal",
                                                              "reached"]
    assert timeline.transitions()[-1]["reason"] == "execute succeeded"


def test_blackboard_writes_name_the_writer_and_skip_unchanged_values(recorded: Recorded) -> None:
    writes = [r for r in recorded.records if r["k"] == "bb"]
    states = [(w["value"], w["by"]) for w in writes if w["key"] == "/agent/state"]
    assert states == [("STARTUP", "agent/agent"), ("IDLE.MANUAL", "agent/agent"), ("IDLE.AUTO", "agent/agent"),
                      ("EXEC", "agent/agent"), ("IDLE.AUTO", "agent/agent")]
    assert not [w for w in writes if w["key"] == "/agent/now"]
    assert any(w["key"].startswith("/monitor/") for w in writes)


def test_poses_at_the_configured_rate(recorded: Recorded) -> None:
    poses = [r for r in recorded.records if r["k"] == "pose"]
    assert [p["t"] for p in poses[:3]] == [0.0, 0.5, 1.0]
    assert (poses[-1]["x"], poses[-1]["y"], poses[-1]["yaw"]) == (3.6, 2.6, 1.0)


@pytest.mark.parametrize("moment", ["idle", "exec", "end"])
def test_a_frame_shows_what_the_live_view_showed_then(recorded: Recorded, moment: str) -> None:
    timeline = TraceTimeline(recorded.records)
    times = sorted(recorded.snapshots)
    exec_times = [t for t in times if recorded.snapshots[t]["state"] == "EXEC"]
    t = {"idle": times[2], "exec": exec_times[len(exec_times) // 2], "end": times[-1]}[moment]
    live, frame = recorded.snapshots[t], timeline.frame(t)
    assert frame["state"] == live["state"] and frame["mode"] == live["mode"] and frame["task"] == live["task"]
    assert shape(frame["tree"]) == shape(live["tree"]) and shape(frame["monitor"]) == shape(live["monitor"])
    for slot in ("tree", "monitor"):  # tick counts: exact at a status change, else recorded once a second
        pairs = list(zip(ticks(frame[slot]), ticks(live[slot]), strict=True))
        assert all(live_n - 10 <= n <= live_n for n, live_n in pairs), pairs
    live_bb = {k: v for k, v in live["blackboard"].items() if k != "/agent/now"}
    assert frame["blackboard"] == live_bb
    assert frame["transitions"][-1]["trigger"] == live["transitions"][-1]["trigger"]


def test_seek_and_step_through_the_changes(recorded: Recorded) -> None:
    timeline = TraceTimeline(recorded.records)
    goal_t = next(r["t"] for r in recorded.records if r["k"] == "tr" and r["trigger"] == "goal")
    before, at = timeline.frame(goal_t - 0.05), timeline.frame(goal_t)
    assert before["state"] == "IDLE.AUTO" and at["state"] == "EXEC"
    assert before["next_t"] == goal_t and at["prev_t"] is not None and at["prev_t"] < goal_t
    assert timeline.frame(-5)["t"] == timeline.start_t and timeline.frame(1e9)["t"] == timeline.end_t
    assert at["pose"] == {"x_m": 2.6, "y_m": 2.6, "yaw_rad": 0.0}


def test_checkpoints_give_the_same_frames(recorded: Recorded, monkeypatch: pytest.MonkeyPatch) -> None:
    plain = TraceTimeline(recorded.records)
    assert len(plain._checkpoints) == 1 + len(recorded.records) // CHECKPOINT_EVERY
    monkeypatch.setattr(trace_timeline, "CHECKPOINT_EVERY", 5)
    checkpointed = TraceTimeline(recorded.records)
    assert len(checkpointed._checkpoints) > 5
    for t in sorted(recorded.snapshots)[::3]:
        assert checkpointed.frame(t) == plain.frame(t)


def test_recorded_to_a_file_and_read_back(agent_spec: AgentSpec, link: RecordingLink, tmp_path: Path) -> None:
    clock = SimClock()
    agent = Agent(agent_spec, RecordingPort(current_pose=Pose2D(1.0, 2.0, 0.5)), link)
    link.time_source = clock.now
    writer = TraceWriter(tmp_path / "run.atrace", max_bytes=5000)
    everything: list[dict[str, Any]] = []

    def tee(record: dict[str, Any]) -> None:
        everything.append(record)
        writer.write(record)

    recorder = AgentRecorder(agent, tee, meta={"map": "studio"})
    writer.preamble = recorder.preamble
    everything.extend(recorder.preamble())
    recorder.attach()
    scheduler = Scheduler(clock)
    scheduler.add(agent, 10.0)
    scheduler.start()
    scheduler.run(duration=1.0)
    for trigger in ("set_auto", "set_manual") * 3 + ("set_auto",):
        agent.submit(trigger)
        scheduler.run(duration=1.0)
    writer.shutdown()
    assert len(writer.parts) > 2  # rotated
    full = TraceTimeline(everything)
    checked = 0
    for part in writer.parts:  # every part replays on its own, as the whole run did
        got = read_trace(part)
        assert got.warnings == []
        timeline = TraceTimeline(got.records)
        assert timeline.head["meta"] == {"map": "studio"}
        inside = sorted({t for t in timeline.times if timeline.start_t < t < timeline.end_t})
        for t in inside[-1:]:
            mine, whole = timeline.frame(t), full.frame(t)
            assert (mine["state"], mine["blackboard"], mine["pose"]) == (whole["state"], whole["blackboard"],
                                                                         whole["pose"])
            assert shape(mine["tree"]) == shape(whole["tree"]) and shape(mine["monitor"]) == shape(whole["monitor"])
            checked += 1
    assert checked >= 2
    assert full.frame(1e9)["state"] == "IDLE.AUTO"


def test_a_failing_recorder_does_not_stop_the_agent(agent_spec: AgentSpec, link: RecordingLink) -> None:
    clock = SimClock()
    agent = Agent(agent_spec, RecordingPort(), link)
    link.time_source = clock.now

    def broken(record: dict[str, Any]) -> None:
        raise OSError("disk gone")

    AgentRecorder(agent, broken).attach()
    scheduler = Scheduler(clock)
    scheduler.add(agent, 10.0)
    scheduler.start()
    scheduler.run(duration=0.5)
    assert agent.state == "IDLE.MANUAL"
    assert any("listener failed" in e and "disk gone" in e for e in agent.errors)
