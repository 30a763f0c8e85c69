"""The depth camera behind the device interface (issue 24): the RealSense D415 drivers where they can be tested
without the camera (the missing extra, the SDK frames' conversion on synthetic arrays, both streams from one
pipeline on the emulated D415) and the simulated one."""

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
from atemr.io.devices import realsense
from atemr.io.devices.config import DepthDeviceConfig
from atemr.io.devices.drivers import DeviceContext, build_device, build_devices, depth_mount, driver_name
from atemr.io.devices.realsense import INSTALL_HINT, Intrinsics, colour_frame, colour_stream_fps, depth_image
from atemr.io.devices.realsense_emulator import LEFT_RGB, RIGHT_RGB, FakeD415
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
    # the colour stream as the camera says so too, at its own key
    config = load_config(environ={}, overrides={"simulation": False, "devices.camera.driver": "realsense"})
    with pytest.raises(ConfigError, match=r"atemr\[realsense\]") as error:
        build_device(DeviceContext(config, time.monotonic), "camera")
    assert error.value.path == "devices.camera.driver"
    with pytest.raises(ConfigError, match=r"atemr\[realsense\]"):
        realsense.D415(now=time.monotonic)


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


# -- the colour stream as the front camera, from the depth's pipeline -------------------------------------------
def d415_config(**overrides):
    return load_config(environ={}, overrides={"simulation": False, "devices.camera.driver": "realsense",
                                              "devices.depth.driver": "realsense", **overrides})


def tick_until(devices, done, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        for device in devices:
            device.tick(time.monotonic())
        time.sleep(0.01)
    return done()


def test_the_colour_frame_is_a_new_rgb_array_of_the_size_asked_for():
    raw = np.zeros((240, 424, 3), dtype=np.uint8)
    raw[:, :, 0] = 255
    frame = colour_frame(raw, 424, 240)
    assert frame.shape == (240, 424, 3) and frame.flags.c_contiguous and not np.shares_memory(frame, raw)
    assert (frame[0, 0] == [255, 0, 0]).all()  # rgb8: red first, as every camera of the robot gives it
    for bad in (np.zeros((480, 640, 3), np.uint8), np.zeros((240, 424), np.uint8), np.zeros((240, 424, 3), np.uint16)):
        with pytest.raises(OSError, match="424 x 240 RGB"):
            colour_frame(bad, 424, 240)
    assert [colour_stream_fps(hz) for hz in (1, 6, 10, 15, 25, 30, 45, 120)] == [6, 6, 15, 15, 30, 30, 60, 60]


def test_depth_and_colour_come_from_one_pipeline_and_both_say_when_the_camera_is_unplugged(monkeypatch):
    """A D415 is opened by one pipeline at a time (the emulator refuses a second, as the device does): the camera
    and depth devices share it, each with its own frames and health, and both come back when it does."""
    d415 = FakeD415(wall_mm=1200)
    monkeypatch.setitem(sys.modules, "pyrealsense2", d415.module())
    config = d415_config(**{"devices.camera.width": 640, "devices.camera.height": 480, "devices.camera.fps": 10,
                            "devices.depth.serial": "822512060000"})
    devices = build_devices(DeviceContext(config, time.monotonic))
    camera, depth = devices.camera, devices.depth
    assert camera is not None and depth is not None
    assert (camera.name, depth.name, camera.rate_hz, depth.rate_hz) == ("camera", "depth", 50.0, 50.0)
    colours: list = []
    camera.subscribe(colours.append)
    try:
        camera.start()
        depth.start()
        assert tick_until([camera, depth], lambda: len(colours) >= 2 and depth.latest is not None)
        assert d415.started == 1 and d415.running == 1  # one pipeline, both streams
        assert ("depth", 424, 240, "z16", 15) in d415.streams and ("color", 640, 480, "rgb8", 15) in d415.streams
        assert ("device", "822512060000") in d415.streams
        frame = colours[-1]
        assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8 and camera.latest is frame
        assert tuple(frame[240, 10]) == LEFT_RGB and tuple(frame[240, 630]) == RIGHT_RGB
        assert float(np.median(depth.latest.depth_m[depth.latest.depth_m > 0])) == pytest.approx(1.2)
        now = time.monotonic()
        assert camera.health(now).ok and depth.health(now).ok
        assert camera.info().kind == "camera" and depth.info().kind == "depth"
        assert camera.info().model == "Intel RealSense D415" and camera.info().driver == "realsense"
        d415.plugged = False
        assert tick_until([camera, depth], lambda: not camera.health(time.monotonic()).ok
                          and not depth.health(time.monotonic()).ok)
        for device in (camera, depth):
            assert "D415" in device.health(time.monotonic()).detail
        d415.plugged = True
        seen = len(colours)
        assert tick_until([camera, depth], lambda: len(colours) > seen + 1 and camera.health(time.monotonic()).ok
                          and depth.health(time.monotonic()).ok)
        assert d415.running == 1
        depth.shutdown()  # the camera still streams while one of its devices runs
        seen = len(colours)
        assert tick_until([camera], lambda: len(colours) > seen)
    finally:
        camera.shutdown()
        depth.shutdown()
    assert d415.running == 0


def test_each_stream_alone_asks_the_pipeline_for_its_own_stream_only(monkeypatch):
    d415 = FakeD415()
    monkeypatch.setitem(sys.modules, "pyrealsense2", d415.module())
    config = d415_config(**{"devices.depth.driver": "none", "devices.camera.width": 424,
                            "devices.camera.height": 240, "devices.camera.fps": 30})
    devices = build_devices(DeviceContext(config, time.monotonic))
    assert devices.depth is None and devices.camera is not None
    try:
        devices.camera.start()
        assert tick_until([devices.camera], lambda: devices.camera.latest is not None)
    finally:
        devices.camera.shutdown()
    assert [s for s in d415.streams if s[0] in ("depth", "color")] == [("color", 424, 240, "rgb8", 30)]
    assert devices.camera.latest.shape == (240, 424, 3)


def test_separate_contexts_would_open_the_camera_twice_and_the_second_is_refused(monkeypatch):
    """What the shared reader prevents: two pipelines on one D415 (the device answers "busy" to the second)."""
    d415 = FakeD415()
    monkeypatch.setitem(sys.modules, "pyrealsense2", d415.module())
    config = d415_config()
    camera = build_device(DeviceContext(config, time.monotonic), "camera")
    depth = build_device(DeviceContext(config, time.monotonic), "depth")
    assert camera is not None and depth is not None
    try:
        camera.start()
        assert tick_until([camera], lambda: camera.latest is not None)
        depth.start()
        assert tick_until([depth], lambda: "busy" in (depth.health(time.monotonic()).detail or ""))
    finally:
        camera.shutdown()
        depth.shutdown()


def test_a_stream_cannot_be_asked_for_twice_nor_after_the_camera_started(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyrealsense2", FakeD415().module())
    config = d415_config()
    reader = realsense.D415(now=time.monotonic)
    stream = reader.colour_stream(config.devices.camera)
    with pytest.raises(RuntimeError, match="already taken"):
        reader.colour_stream(config.devices.camera)
    stream.start()
    try:
        with pytest.raises(RuntimeError, match="after its pipeline started"):
            reader.depth_stream(config.devices.depth, CameraMount())
    finally:
        stream.shutdown()


def test_the_drivers_sdk_calls_are_the_real_pyrealsense2s_and_a_missing_camera_is_said_at_once():
    """With the realsense extra installed (./test installs it): the names the driver calls, and those the emulator
    stands in for, exist in the real SDK; with no camera connected (none is, here) the driver says so at once,
    instead of waiting in ``pipeline.start`` for the 15 s librealsense gives a camera to appear."""
    rs = pytest.importorskip("pyrealsense2", reason="the realsense extra (pyrealsense2) is not installed")
    for path in ("pipeline", "config", "context", "stream.depth", "stream.color", "format.z16", "format.rgb8",
                 "camera_info.name", "camera_info.firmware_version", "camera_info.serial_number"):
        target = rs
        for part in path.split("."):
            target = getattr(target, part)
    fake = FakeD415().module()
    for space in ("stream", "format", "camera_info"):
        assert set(vars(getattr(fake, space))) <= set(dir(getattr(rs, space))), space
    config = rs.config()  # the calls the driver makes before a camera is needed, with its argument order
    config.enable_device("822512060000")
    config.enable_stream(rs.stream.depth, 424, 240, rs.format.z16, 15)
    config.enable_stream(rs.stream.color, 640, 480, rs.format.rgb8, 15)
    camera = realsense.D415(now=time.monotonic, serial="822512060000")
    stream = camera.colour_stream(load_config(environ={}).devices.camera)
    began = time.monotonic()
    stream.start()
    try:
        assert tick_until([stream], lambda: "no RealSense camera connected"
                          in (stream.health(time.monotonic()).detail or ""), timeout_s=5.0)
        assert "USB 3" in (stream.health(time.monotonic()).detail or "")  # and what to check
    finally:
        stream.shutdown()
    assert time.monotonic() - began < 5.0
