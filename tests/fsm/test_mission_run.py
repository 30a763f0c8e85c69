"""`run_mission`: a mission run to its end on an agent ticked by a scheduler, with its JSON result."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from atemr.clock import SimClock
from atemr.errors import ConfigError
from atemr.fsm.agent import Agent
from atemr.fsm.mission_run import run_mission
from atemr.fsm.spec import AgentSpec
from atemr.msgs import Pose2D
from atemr.scheduler import Scheduler
from atemr.trees.fakes import RecordingLink, RecordingPort, StraightLineNavigation
from atemr.trees.missions import load_mission, mission_from_goals, parse_mission
from atemr.yamlsafe import load_yaml

MISSIONS = Path(__file__).resolve().parents[2] / "trees" / "missions"


def robot(spec: AgentSpec, port: RecordingPort, *, navigation: bool = False) -> tuple[Agent, Scheduler]:
    clock = SimClock()
    link = RecordingLink(time_source=clock.now)
    agent = Agent(spec, port, link, navigation=StraightLineNavigation(port) if navigation else None)
    scheduler = Scheduler(clock)
    scheduler.add(agent, 10.0)
    return agent, scheduler


def test_look_around_runs_to_its_end(agent_spec: AgentSpec) -> None:
    port = RecordingPort(dt_s=0.1)
    agent, scheduler = robot(agent_spec, port)
    result = run_mission(agent, scheduler.step, load_mission(MISSIONS / "look-around.yaml"))
    result = json.loads(json.dumps(result))
    assert result["outcome"] == "reached" and result["reason"] is None
    assert [s["status"] for s in result["steps"]] == ["reached"] * 9
    assert result["final_pose"]["yaw_rad"] == pytest.approx(2 * math.pi, abs=0.2)
    assert [r["dest"] for r in result["trace"]] == ["STARTUP", "IDLE.MANUAL", "IDLE.AUTO", "EXEC", "IDLE.AUTO"]
    assert len(port.images) == 4 and result["state"] == "IDLE.AUTO"


def test_a_mission_the_build_cannot_run_is_not_started_with_the_reason(agent_spec: AgentSpec) -> None:
    agent, scheduler = robot(agent_spec, RecordingPort())
    result = run_mission(agent, scheduler.step, load_mission(MISSIONS / "kitchen-check.yaml"))
    assert result["outcome"] == "not started"
    assert result["reason"].endswith("drives to poses (steps 0, 5) and navigation is not available on this robot")
    goals = run_mission(agent, scheduler.step, mission_from_goals([Pose2D(1, 2, 0), Pose2D(3, 4, 1)]))
    assert goals["outcome"] == "not started" and "navigation is not available" in goals["reason"]


def test_goals_are_visited_in_order_with_navigation(agent_spec: AgentSpec) -> None:
    port = RecordingPort(current_pose=Pose2D(0, 0, 0))
    agent, scheduler = robot(agent_spec, port, navigation=True)
    result = run_mission(agent, scheduler.step, mission_from_goals([Pose2D(1, 0, 0), Pose2D(1, 1, 1.5)]))
    assert result["outcome"] == "reached" and result["final_pose"] == {"x_m": 1.0, "y_m": 1.0, "yaw_rad": 1.5}
    first, second = result["steps"]
    assert first["finished_s"] <= second["started_s"] and second["position_error_m"] == 0.0


def test_start_up_failure_and_timeout(agent_spec: AgentSpec) -> None:
    port = RecordingPort()
    del port.components["imu"]
    agent, scheduler = robot(agent_spec, port)
    result = run_mission(agent, scheduler.step, load_mission(MISSIONS / "look-around.yaml"), startup_timeout_s=10)
    assert result["outcome"] == "not started" and "did not reach IDLE" in result["reason"]
    assert result["state"] == "SHUTDOWN.POWEROFF"

    agent, scheduler = robot(agent_spec, RecordingPort())
    slow = parse_mission(load_yaml("s", text="mission:\n  name: s\n  steps: [{wait: {duration_s: 60}}]\n"), "s")
    result = run_mission(agent, scheduler.step, slow, timeout_s=2.0)
    assert result["outcome"] == "timeout" and "cancelled" in result["reason"]
    assert result["steps"][0]["status"] == "interrupted"


def test_goals_must_be_given_and_finite() -> None:
    with pytest.raises(ConfigError, match="at least one goal"):
        mission_from_goals([])
    with pytest.raises(ConfigError, match="goal 1 has a non-finite coordinate"):
        mission_from_goals([Pose2D(0, 0, 0), Pose2D(math.nan, 0, 0)])
    mission = mission_from_goals([Pose2D(1, 2, 0.5)], timeout_s=30)
    assert mission.spec.children[0].type == "Timeout" and mission.steps[0].behaviours == ("GoToPose",)
