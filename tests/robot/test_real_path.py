"""The real robot's path, proven without the hardware: ``simulation: false`` on the wall clock, the real
RPLidar and WT901 drivers reading byte-level emulators on pseudo-terminals that a simulated world feeds, and
the motors and the secondary core ``emulated`` on a virtual CAN bus in the robot's process (this kernel has no
CAN support, so socketcan cannot be used here).

One robot, one run, with an OpenCV camera reading a video file: it reaches IDLE; it starts unlocalized on no
map; once the operator selects the map and sets the pose it switches to AUTO and drives to a goal 1.5 m away;
the camera's frames reach a capture; when the lidar is unplugged, motion stops and the agent goes to ERROR
naming the lidar; when the lidar comes back, the agent recovers to IDLE.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from atemr.config import load_config
from atemr.fsm.agent import Agent
from atemr.io.can.bus import unique_channel
from atemr.io.devices.camera import OpenCvCamera
from atemr.io.devices.rplidar import RplidarDriver
from atemr.io.devices.rplidar_emulator import RplidarEmulator
from atemr.io.devices.wt901 import Wt901Driver
from atemr.io.devices.wt901_emulator import Wt901Emulator
from atemr.io.recording.mcap_reader import RecordingReader
from atemr.msgs import Pose2D
from atemr.robot import build_robot
from atemr.robot.core import Robot

GOAL_M = 1.5


def red_video(path: Path) -> Path:
    """A short MJPG video of a red scene: what the front camera sees here (OpenCV reads it as a V4L2 camera)."""
    cv2 = pytest.importorskip("cv2", reason="the opencv camera driver needs OpenCV (the camera extra)")
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    assert writer.isOpened(), "OpenCV cannot write MJPG .avi files here"
    try:
        for _ in range(10):
            writer.write(np.full((48, 64, 3), (0, 0, 255), dtype=np.uint8))  # BGR: red
    finally:
        writer.release()
    return path


@pytest.fixture
def real_robot(tmp_path: Path) -> Iterator[tuple[Robot, RplidarEmulator, Wt901Emulator]]:
    video = red_video(tmp_path / "front.avi")
    with RplidarEmulator(directory=tmp_path) as lidar, Wt901Emulator(directory=tmp_path) as imu:
        config = load_config(None, environ={}, overrides={
            "simulation": False, "data_dir": tmp_path / "data", "ui.enabled": False, "control.enabled": False,
            "trace.enabled": True, "can.channel": unique_channel("real"), "sim.world": "studio",
            "devices.lidar.driver": "rplidar", "devices.lidar.port": lidar.port,
            "devices.imu.driver": "wt901", "devices.imu.port": imu.port, "devices.imu.bias_s": 0.5,
            "devices.camera.driver": "opencv", "devices.camera.source": str(video),
            "devices.camera.width": 64, "devices.camera.height": 48, "devices.motors.driver": "emulated",
            "devices.secondary.driver": "emulated",
        })
        robot = build_robot(config, realtime=True)
        sim = robot.parts.sim
        lidar.feed = lambda: sim.lidar_source.latest  # the world the emulated motors drive in
        imu.feed = lambda: sim.imu_source.latest
        with robot:
            yield robot, lidar, imu


def run_until(robot: Robot, done: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Run the robot on the wall clock until ``done()`` (checked every 0.1 s), or fail saying what."""
    deadline = time.monotonic() + timeout_s
    while not done():
        if time.monotonic() > deadline:
            agent = robot.components["agent"]
            raise AssertionError(f"not {what} within {timeout_s} s: agent in {agent.state}, "  # type: ignore[attr-defined]
                                 f"health {robot.parts.health.collect()}")
        robot.run(duration=0.1)


@pytest.mark.exclusive  # a real-time robot: blind stop within 2 s of the wall clock
def test_the_real_path_drives_to_a_goal_and_stops_blind(real_robot: tuple[Robot, RplidarEmulator,
                                                                          Wt901Emulator]) -> None:
    robot, lidar, _ = real_robot
    agent = robot.components["agent"]
    assert isinstance(agent, Agent)
    assert isinstance(robot.devices.lidar, RplidarDriver) and isinstance(robot.devices.imu, Wt901Driver)
    assert isinstance(robot.devices.camera, OpenCvCamera)
    run_until(robot, lambda: agent.state.startswith("IDLE"), 15, "in IDLE")
    health = robot.parts.health
    run_until(robot, lambda: all(h.ok for h in health.collect().values()), 10, "healthy")  # the board boots

    maps, localization, sim = robot.parts.maps, robot.parts.localization, robot.parts.sim
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

    # The front camera's frames reach a capture exactly as the simulated camera's do.
    image = Image.open(robot.parts.port.capture_image("front"))
    red, green, blue = np.asarray(image.convert("RGB"), dtype=float).reshape(-1, 3).mean(axis=0)
    assert image.size == (64, 48) and red > 200 and green < 60 and blue < 60

    # The lidar's cable comes out mid-run: the robot is blind, so it stops and says why.
    agent.submit("set_manual")
    run_until(robot, lambda: agent.state == "IDLE.MANUAL", 3, "in MANUAL")
    lidar.unplug()
    unplugged = time.monotonic()
    run_until(robot, lambda: agent.state == "ERROR", 3, "in ERROR")
    assert time.monotonic() - unplugged < 2.0
    error = agent.snapshot()["error"]
    assert "lidar" in str(error), error
    assert robot.parts.driver.commanded.left_radps == 0.0 == robot.parts.driver.commanded.right_radps
    lidar.replug()
    run_until(robot, lambda: agent.state.startswith("IDLE"), 10, "recovered")
    assert robot.devices.lidar.health(robot.clock.now()).ok

    # The run was recorded from the real drivers (a writer thread on the wall clock), as a simulated run is.
    writer = robot.parts.trace
    assert writer is not None and writer.threaded, writer
    assert writer.error is None, writer.error
    writer.flush()
    reader = RecordingReader(writer.parts[0])
    counts = Counter(m.topic for m in reader.messages())
    for topic in ("/scan", "/imu", "/wheel_odom", "/odom", "/pose", "/tf", "/map", "/plan", "/can/frames",
                  "/camera/image/compressed", "/health", "/agent/transitions"):
        assert counts[topic] > 0, (topic, counts)
    assert counts["/scan"] > 50 and counts["/imu"] > counts["/scan"]
