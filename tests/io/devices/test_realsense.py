"""The depth camera behind the device interface (issue 24): the RealSense D415 driver where it can be tested
without the camera (the missing extra, the SDK frame's conversion on synthetic arrays) and the simulated one."""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.errors import ConfigError
from atemr.io.devices.config import DepthDeviceConfig
from atemr.io.devices.drivers import DeviceContext, build_device, depth_mount, driver_name
from atemr.io.devices.realsense import INSTALL_HINT, Intrinsics, RealSenseDepth, depth_image
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.msgs import CameraMount, DepthImage
from atemr.scheduler import Scheduler
from atemr.skills.depth_cloud import depth_to_points

ROOT = Path(__file__).resolve().parents[3]
D415 = Intrinsics(fx=305.0, fy=305.0, ppx=211.5, ppy=119.5)  # about the D415's depth intrinsics at 424 x 240


def test_without_pyrealsense2_configuring_the_realsense_driver_names_the_extra(monkeypatch):
    # importing the driver modules does not import the SDK (a simulated robot never needs it) ...
    script = ("import sys\nimport atemr.io.devices.realsense, atemr.io.devices.drivers\n"
              "assert 'pyrealsense2' not in sys.modules\n")
    subprocess.run([sys.executable, "-c", script], check=True, cwd=ROOT, timeout=60)
    # ... and configuring the robot with it says what to install, naming the key
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    config = load_config(environ={}, overrides={"simulation": False, "devices.depth.driver": "realsense"})
    with pytest.raises(ConfigError, match=r"pip install 'atemr\[realsense\]'") as error:
        build_device(DeviceContext(config, time.monotonic), "depth")
    assert INSTALL_HINT in str(error.value) and error.value.path == "devices.depth.driver"
    with pytest.raises(ConfigError, match=r"atemr\[realsense\]"):
        RealSenseDepth.from_config(DepthDeviceConfig(driver="realsense"), now=time.monotonic, mount=CameraMount())


def test_the_sdk_frame_becomes_metres_with_no_data_and_far_readings_as_zero():
    raw = np.full((240, 424), 1500, dtype=np.uint16)  # 1.5 m in the D415's 1 mm units
    raw[0, 0] = 0  # no data
    raw[1, 1] = 200  # 0.2 m: under the minimum range
    raw[2, 2] = 5000  # 5 m: beyond the configured 3 m
    mount = CameraMount(x_m=0.1, z_m=0.85, pitch_rad=0.0)
    image = depth_image(raw, 0.001, D415, mount, t=12.5, range_max_m=3.0)
    assert image.depth_m.dtype == np.float32 and image.depth_m.shape == (240, 424)
    assert image.depth_m[5, 5] == pytest.approx(1.5)
    assert image.depth_m[0, 0] == image.depth_m[1, 1] == image.depth_m[2, 2] == 0.0
    assert (image.fx, image.fy, image.cx, image.cy) == (305.0, 305.0, 211.5, 119.5)
    assert (image.t, image.mount, image.range_min_m, image.range_max_m) == (12.5, mount, 0.3, 3.0)
    assert not np.shares_memory(image.depth_m, raw)


def test_a_wall_seen_by_the_d415_lands_in_the_base_frame_where_it_is():
    raw = np.full((240, 424), 1500, dtype=np.uint16)
    image = depth_image(raw, 0.001, D415, CameraMount(x_m=0.1, z_m=0.85), t=0.0)
    points = depth_to_points(image)
    assert points[:, 0] == pytest.approx(np.full(len(points), 1.6), abs=1e-5)  # 1.5 m ahead of a camera 0.1 m out
    centre = points.reshape(240, 424, 3)[119, 211]
    # half a pixel up and left of the principal point: a hair left (y > 0) and above the camera (z > 0.85)
    assert centre == pytest.approx([1.6, 1.5 * 0.5 / 305.0, 0.85 + 1.5 * 0.5 / 305.0], abs=1e-5)
    assert np.ptp(points[:, 2]) == pytest.approx(1.5 * 239 / 305.0, abs=1e-3)  # the vertical field of view


@pytest.mark.parametrize("raw, scale", [(np.zeros((4, 4), dtype=np.float32), 0.001),
                                        (np.zeros((4, 4, 3), dtype=np.uint16), 0.001),
                                        (np.zeros((4, 4), dtype=np.uint16), 0.0)])
def test_a_frame_that_is_not_depth_is_a_read_error(raw, scale):
    with pytest.raises(OSError):  # the reader thread then reopens the camera, as for an unplugged one
        depth_image(raw, scale, D415, CameraMount(), t=0.0)


def test_auto_is_the_simulator_in_simulation_and_none_on_the_robot():
    assert driver_name(load_config(environ={}), "depth") == "sim"
    real = load_config(environ={}, overrides={"simulation": False})
    assert driver_name(real, "depth") == "none"
    assert build_device(DeviceContext(real, time.monotonic), "depth") is None


def test_the_mount_comes_from_the_pose_and_a_bad_pose_is_refused():
    assert depth_mount(DepthDeviceConfig()) == CameraMount(0.10, 0.0, 0.85, 0.2094, 0.0)
    with pytest.raises(ConfigError, match=r"devices\.depth"):
        load_config(environ={}, overrides={"devices.depth.pose": "0.1,0,0.85"})


def test_the_simulated_depth_camera_is_a_device_with_health():
    clock = SimClock()
    sim = build_simulation("studio", 0, params=SimParams(depth_hz=10.0))
    config = load_config(environ={})
    device = build_device(DeviceContext(config, clock.now, sim), "depth")
    assert device is not None and device.name == "depth" and device.rate_hz is None
    assert not device.health(clock.now()).ok
    frames: list[DepthImage] = []
    device.subscribe(frames.append)
    scheduler = Scheduler(clock)
    sim.attach(scheduler)
    scheduler.run(duration=1.0)
    assert device.health(clock.now()).ok
    assert len(frames) == 11 and frames[-1] is device.latest
    assert frames[-1].depth_m.shape == (240, 424) and math.isclose(frames[-1].t, 1.0)
    assert device.info().driver == "sim"
    none = build_device(DeviceContext(config, clock.now, build_simulation("studio", 0)), "depth")
    assert none is None  # sim.depth_hz 0 in a bare simulation: no frames, no device
