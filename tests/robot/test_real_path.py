"""The real robot's path, proven without the hardware: ``simulation: false`` on the wall clock, the real
RPLidar and WT901 drivers reading byte-level emulators on pseudo-terminals that a simulated world feeds, and
the motors and the secondary core ``emulated`` on a virtual CAN bus in the robot's process (this kernel has no
CAN support, so socketcan cannot be used here).

One robot, one run: it reaches IDLE; it starts unlocalized on no map; once the operator selects the map and
sets the pose it switches to AUTO and drives to a goal 1.5 m away; when the lidar is unplugged, motion stops
and the agent goes to ERROR naming the lidar; when the lidar comes back, the agent recovers to IDLE.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from atemr.config import load_config
from atemr.fsm.agent import Agent
from atemr.io.can.bus import unique_channel
from atemr.io.devices.rplidar import RplidarDriver
from atemr.io.devices.rplidar_emulator import RplidarEmulator
from atemr.io.devices.wt901 import Wt901Driver
from atemr.io.devices.wt901_emulator import Wt901Emulator
from atemr.msgs import Pose2D
from atemr.robot import build_robot
from atemr.robot.core import Robot

GOAL_M = 1.5


@pytest.fixture
def real_robot(tmp_path: Path) -> Iterator[tuple[Robot, RplidarEmulator, Wt901Emulator]]:
    with RplidarEmulator(directory=tmp_path) as lidar, Wt901Emulator(directory=tmp_path) as imu:
        config = load_config(None, environ={}, overrides={
            "simulation": False, "data_dir": tmp_path / "data", "ui.enabled": False, "control.enabled": False,
            "trace.enabled": False, "can.channel": unique_channel("real"), "sim.world": "studio",
            "devices.lidar.driver": "rplidar", "devices.lidar.port": lidar.port,
            "devices.imu.driver": "wt901", "devices.imu.port": imu.port, "devices.imu.bias_s": 0.5,
            "devices.camera.driver": "none", "devices.motors.driver": "emulated",
            "devices.secondary.driver": "emulated",
        })
        robot = build_robot(config, realtime=True)
        sim = robot.extras["sim"]
        lidar.feed = lambda: sim.lidar_source.latest  # the world the emulated motors drive in
        imu.feed = lambda: sim.imu_source.latest
        with robot:
            yield robot, lidar, imu


def run_until(robot: Robot, done: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Run the robot on the wall clock until ``done()`` (checked every 0.1 s), or fail saying what."""
    deadline = time.monotonic() + timeout_s
    while not done():
        if time.monotonic() > deadline:
            agent = robot.parts["agent"]
            raise AssertionError(f"not {what} within {timeout_s} s: agent in {agent.state}, "  # type: ignore[attr-defined]
                                 f"health {robot.extras['health'].collect()}")
        robot.run(duration=0.1)


def test_the_real_path_drives_to_a_goal_and_stops_blind(real_robot: tuple[Robot, RplidarEmulator,
                                                                          Wt901Emulator]) -> None:
    robot, lidar, _ = real_robot
    agent = robot.parts["agent"]
    assert isinstance(agent, Agent)
    assert isinstance(robot.devices.lidar, RplidarDriver) and isinstance(robot.devices.imu, Wt901Driver)
    run_until(robot, lambda: agent.state.startswith("IDLE"), 15, "in IDLE")
    health = robot.extras["health"]
    run_until(robot, lambda: all(h.ok for h in health.collect().values()), 10, "healthy")  # the board boots

    maps, localization, sim = robot.extras["maps"], robot.extras["localization"], robot.extras["sim"]
    assert maps.active_name is None and localization.map_pose() is None, "a real robot starts on no map, unlocalized"
    refused = agent.submit("set_auto")
    run_until(robot, lambda: agent.result(refused) is not None, 2, "answered")
    assert agent.state == "IDLE.MANUAL", "AUTO needs a map and a pose"
    assert "not localized" in str(agent.result(refused)), agent.result(refused)

    # The operator selects the world's map and clicks where the robot stands.
    maps.activate(sim.world.name, sim.world.map)
    localization.set_initial_pose(robot.clock.now(), sim.pose)
    run_until(robot, lambda: localization.map_pose() is not None, 3, "localized")
    auto = agent.submit("set_auto")
    run_until(robot, lambda: agent.result(auto) is not None, 2, "answered")
    assert agent.state == "IDLE.AUTO", agent.result(auto)
    start = sim.pose
    goal = Pose2D(start.x_m + GOAL_M, start.y_m, 0.0)
    agent.submit("goal", goal=goal)
    run_until(robot, lambda: agent.state == "EXEC", 3, "executing the goal")
    run_until(robot, lambda: agent.state != "EXEC", 40, "done with the goal")
    assert agent.state == "IDLE.AUTO", agent.snapshot()
    truth = sim.pose
    assert math.hypot(truth.x_m - goal.x_m, truth.y_m - goal.y_m) < 0.35, truth
    assert not sim.collisions

    # The lidar's cable comes out mid-run: the robot is blind, so it stops and says why.
    agent.submit("set_manual")
    run_until(robot, lambda: agent.state == "IDLE.MANUAL", 3, "in MANUAL")
    lidar.unplug()
    unplugged = time.monotonic()
    run_until(robot, lambda: agent.state == "ERROR", 3, "in ERROR")
    assert time.monotonic() - unplugged < 2.0
    error = agent.snapshot()["error"]
    assert "lidar" in str(error), error
    assert robot.extras["driver"].commanded.left_radps == 0.0 == robot.extras["driver"].commanded.right_radps
    lidar.replug()
    run_until(robot, lambda: agent.state.startswith("IDLE"), 10, "recovered")
    assert robot.devices.lidar.health(robot.clock.now()).ok
