"""The agent driving the real Navigator through `NavigatorPort`, on a hand-made two-room map with a
kinematic base (the pose follows each commanded twist for one agent period)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.clock import SimClock
from atemr.domain.maps import OccupancyMap
from atemr.fsm.agent import Agent
from atemr.fsm.spec import AgentSpec
from atemr.io.sim.base import integrate_arc
from atemr.msgs import Pose2D, Twist
from atemr.robot.navigator_port import NavigatorPort
from atemr.scheduler import Scheduler
from atemr.skills.nav.navigator import Navigator
from atemr.trees.fakes import RecordingLink, RecordingPort
from atemr.trees.ports import VelocitySource

DT = 0.1


def two_rooms() -> OccupancyMap:
    """Two 2.4 m rooms joined by a 1 m doorway at x = 2.5 m (the navigator's own test map)."""
    data = np.zeros((60, 100), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 48:52] = 100
    data[20:40, 48:52] = 0
    return OccupancyMap(data, 0.05, Pose2D(0.0, 0.0, 0.0), name="two-rooms")


@dataclass
class KinematicPort(RecordingPort):
    """Moves ``current_pose`` by every navigation/agent command for one agent period."""

    def command_velocity(self, source: VelocitySource, twist: Twist, now: float) -> None:
        self.commands.append((source, twist, now))
        if source != "joystick" and self.current_pose is not None:
            self.current_pose = integrate_arc(self.current_pose, twist.linear_mps, twist.angular_radps, DT)


def rig(spec: AgentSpec) -> tuple[Agent, Scheduler, KinematicPort, Navigator]:
    port = KinematicPort(current_pose=Pose2D(0.8, 0.8, 0.0))
    navigator = Navigator(two_rooms())
    clock = SimClock()
    agent = Agent(spec, port, RecordingLink(time_source=clock.now),
                  navigation=NavigatorPort(navigator, pose=port.pose))
    scheduler = Scheduler(clock)
    scheduler.add(agent, 1 / DT)
    scheduler.run(duration=0.3)
    agent.submit("set_auto")
    scheduler.run(duration=0.3)
    assert agent.state == "IDLE.AUTO"
    return agent, scheduler, port, navigator


def test_a_goal_in_the_other_room_is_reached(agent_spec: AgentSpec) -> None:
    agent, scheduler, port, navigator = rig(agent_spec)
    goal = Pose2D(4.0, 1.5, math.pi / 2)
    agent.submit("goal", goal=goal)
    scheduler.run(duration=0.5)
    assert agent.state == "EXEC"
    left = agent.snapshot()["task_progress"]["steps"][0]["distance_left_m"]
    assert left > 3.0
    scheduler.run(duration=60.0)
    assert agent.state == "IDLE.AUTO"
    report = agent.task_reports[-1]
    assert report["outcome"] == "reached"
    step = report["steps"][0]
    assert step["position_error_m"] <= 0.25 and step["heading_error_rad"] <= 0.13
    assert port.commands[-1][1] == Twist() and navigator.state == "SUCCEEDED"


def test_a_goal_in_a_wall_is_refused_with_the_navigators_reason(agent_spec: AgentSpec) -> None:
    agent, scheduler, _, _ = rig(agent_spec)
    agent.submit("goal", goal=Pose2D(2.5, 0.5, 0.0))
    scheduler.run(duration=0.2)
    refused = next(r for r in agent.trace if r.trigger == "goal")
    assert refused.dest == "ERROR" and "obstacle" in refused.reason
    assert agent.state == "IDLE.AUTO"  # the error handled: AUTO again, ready for a goal that is not in a wall
    agent.submit("set_manual")
    scheduler.run(duration=0.2)
    agent.submit("goal", goal=Pose2D(4.0, 1.5, 0.0))  # a good goal, but in MANUAL: an invalid goal as well
    scheduler.run(duration=0.2)
    assert agent.results[-1].dest == "ERROR" and "AUTO mode only" in agent.results[-1].reason


def test_cancel_cancels_the_navigator(agent_spec: AgentSpec) -> None:
    agent, scheduler, port, navigator = rig(agent_spec)
    agent.submit("goal", goal=Pose2D(4.0, 1.5, 0.0))
    scheduler.run(duration=2.0)
    agent.submit("cancel")
    scheduler.run(duration=0.2)
    assert agent.state == "IDLE.AUTO" and navigator.state == "CANCELED"
    assert port.commands[-1][1] == Twist()
    assert agent.task_reports[-1]["outcome"] == "cancelled"
