"""The RealSense D415 on the whole robot (issue 24): its colour stream is the front camera and its depth feeds
the depth obstacle layer, both from one pipeline, on the emulated camera (pyrealsense2's API, see
`atemr.io.devices.realsense_emulator`) while the simulated world gives the lidar, IMU and motors, on the wall
clock as the real robot runs."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from atemr.config import load_config
from atemr.io.can.bus import unique_channel
from atemr.io.devices.realsense import D415Stream
from atemr.io.devices.realsense_emulator import LEFT_RGB, RIGHT_RGB, FakeD415
from atemr.robot import build_robot

from .test_real_path import run_until


@pytest.mark.exclusive  # a robot on the wall clock
def test_the_d415_is_the_robots_camera_and_its_depth_sensor(tmp_path: Path, monkeypatch) -> None:
    d415 = FakeD415(wall_mm=1000)  # a wall 1 m in front of the camera
    monkeypatch.setitem(sys.modules, "pyrealsense2", d415.module())
    config = load_config(None, environ={}, overrides={
        "data_dir": tmp_path, "ui.enabled": False, "control.enabled": False, "trace.enabled": False,
        "can.channel": unique_channel("d415"), "devices.camera.driver": "realsense",
        "devices.camera.width": 424, "devices.camera.height": 240, "devices.camera.fps": 10,
        "devices.depth.driver": "realsense"})
    robot = build_robot(config, realtime=True)
    camera, depth = robot.devices.camera, robot.devices.depth
    assert isinstance(camera, D415Stream) and isinstance(depth, D415Stream) and camera.camera is depth.camera
    with robot:
        health = robot.parts.health
        run_until(robot, lambda: health.collect()["camera"].ok and health.collect()["depth"].ok, 10,
                  "with both streams healthy")
        assert d415.started == 1 and d415.running == 1  # one pipeline for both

        # the carer's capture is the D415's colour picture, as any camera's frames are
        image = np.asarray(Image.open(robot.parts.port.capture_image("front")).convert("RGB"), dtype=float)
        assert image.shape == (240, 424, 3)
        assert np.abs(image[120, 20] - LEFT_RGB).max() < 30 and np.abs(image[120, 400] - RIGHT_RGB).max() < 30

        # the depth frames reach the obstacle layer: the wall stands about 1.1 m ahead of the base
        pose = robot.parts.localization.map_pose()
        assert pose is not None, "the simulated robot starts localized on the studio"
        run_until(robot, lambda: len(robot.parts.navigation.depth_obstacles()) > 0, 5, "with depth obstacles")
        points = robot.parts.navigation.depth_obstacles()
        ahead = (points[:, 0] - pose.x_m) * np.cos(pose.yaw_rad) + (points[:, 1] - pose.y_m) * np.sin(pose.yaw_rad)
        assert 0.8 < float(np.median(ahead)) < 1.4, np.median(ahead)

        # unplugged: both devices say why; back: both recover
        d415.plugged = False
        run_until(robot, lambda: not health.collect()["camera"].ok and not health.collect()["depth"].ok, 5,
                  "with both streams unhealthy")
        assert "D415" in (health.collect()["camera"].detail or "")
        d415.plugged = True
        run_until(robot, lambda: health.collect()["camera"].ok and health.collect()["depth"].ok, 5, "recovered")
    assert d415.running == 0
