"""Device drivers by name, one registry per device kind, and `build_devices` that the robot's wiring calls.

Like the CAN bus kinds (`atemr.io.can.bus`), drivers are registered by name and a third-party package adds
its own through the ``atemr.lidar_drivers`` / ``atemr.imu_drivers`` / ``atemr.camera_drivers`` /
``atemr.depth_drivers`` entry-point groups. A driver is a factory: `DeviceContext` in, a `Device` out (or None
for ``camera: none`` and ``depth: none``). Real
drivers are imported only when chosen, so a simulated robot never imports pyserial or OpenCV.

The CAN devices (motors, secondary core) have no factory here: the primary's motor driver and secondary
link always run, and their ``emulated`` drivers are the emulators the wiring puts on the robot's bus.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from atemr.config import Config
from atemr.errors import ConfigError
from atemr.io.devices.base import Device
from atemr.io.devices.config import SIMULATED_DRIVERS, DepthDeviceConfig, resolved_driver
from atemr.io.sim.simulation import PeriodicSource, Simulation
from atemr.msgs import CameraMount, DepthImage, ImuSample, LaserScan
from atemr.registry import Registry

if TYPE_CHECKING:
    from atemr.io.devices.realsense import D415

#: How old the newest simulated reading may be before the device counts as silent, in seconds.
SIM_MAX_AGE_S = {"lidar": 0.5, "imu": 0.2}


@dataclass(frozen=True)
class DeviceContext:
    """What a driver factory may use: the configuration, the robot's clock, the simulated world if any, and
    ``shared``: what drivers of one robot share, such as the one RealSense pipeline both the depth and the
    camera drivers read (build every device of a robot with one context)."""

    config: Config
    now: Callable[[], float]
    sim: Simulation | None = None
    shared: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def world(self, kind: str) -> Simulation:
        """The simulation, for a ``sim`` driver; an error naming the device when there is none."""
        if self.sim is None:
            raise ConfigError("driver 'sim' needs the simulated world, and none runs",
                              path=f"devices.{kind}.driver")
        return self.sim


DeviceFactory = Callable[[DeviceContext], Device[Any] | None]

lidar_drivers: Registry[DeviceFactory] = Registry("lidar_drivers")
imu_drivers: Registry[DeviceFactory] = Registry("imu_drivers")
camera_drivers: Registry[DeviceFactory] = Registry("camera_drivers")
depth_drivers: Registry[DeviceFactory] = Registry("depth_drivers")
REGISTRIES = {"lidar": lidar_drivers, "imu": imu_drivers, "camera": camera_drivers, "depth": depth_drivers}

Frame = NDArray[np.uint8]


@dataclass(frozen=True)
class Devices:
    """The robot's sensors, each behind the device interface; the cameras may be absent."""

    lidar: Device[LaserScan]
    imu: Device[ImuSample]
    camera: Device[Frame] | None
    depth: Device[DepthImage] | None = None

    def all(self) -> list[Device[Any]]:
        """Every device present, lidar first."""
        return [d for d in (self.lidar, self.imu, self.camera, self.depth) if d is not None]


def depth_mount(cfg: DepthDeviceConfig) -> CameraMount:
    """Where ``devices.depth.pose`` puts the depth camera on the robot."""
    x, y, z, pitch, yaw = cfg.pose
    return CameraMount(x, y, z, pitch, yaw)


def _sim_device(kind: str, ctx: DeviceContext, what: str, max_age_s: float) -> Device[Any]:
    from atemr.io.devices.sim import SimDevice

    sim = ctx.world(kind)
    sources: dict[str, PeriodicSource[Any]] = {"lidar": sim.lidar_source, "imu": sim.imu_source,
                                               "camera": sim.camera_source, "depth": sim.depth_source}
    return SimDevice(kind, sources[kind], max_age_s=max_age_s, what=what, world=sim.world.name)


@lidar_drivers.register("sim")
def sim_lidar(ctx: DeviceContext) -> Device[Any]:
    """The simulator's lidar (ray casting on the world's map and objects)."""
    return _sim_device("lidar", ctx, "scan", SIM_MAX_AGE_S["lidar"])


@imu_drivers.register("sim")
def sim_imu(ctx: DeviceContext) -> Device[Any]:
    """The simulator's IMU (the base's true motion with MEMS noise)."""
    return _sim_device("imu", ctx, "IMU sample", SIM_MAX_AGE_S["imu"])


def _sim_frames(kind: str, ctx: DeviceContext, what: str, rate_hz: Callable[[Simulation], float]) -> Device[Any] | None:
    """A simulated camera's frames as a device (silent after three frame periods, at least 1 s); none when the
    simulation renders none (its rate is 0)."""
    hz = rate_hz(ctx.world(kind))
    return None if hz <= 0 else _sim_device(kind, ctx, what, max(1.0, 3.0 / hz))


@camera_drivers.register("sim")
def sim_camera(ctx: DeviceContext) -> Device[Any] | None:
    """The simulator's camera; none when ``sim.camera_hz`` is 0."""
    return _sim_frames("camera", ctx, "camera frame", lambda sim: sim.params.camera_hz)


@camera_drivers.register("none")
def no_camera(ctx: DeviceContext) -> None:
    """No camera on this robot."""
    return None


@depth_drivers.register("sim")
def sim_depth(ctx: DeviceContext) -> Device[Any] | None:
    """The simulator's depth camera (a D415 rendering the same scene); none when ``sim.depth_hz`` is 0."""
    return _sim_frames("depth", ctx, "depth frame", lambda sim: sim.params.depth_hz)


@depth_drivers.register("none")
def no_depth(ctx: DeviceContext) -> None:
    """No depth camera on this robot: the obstacle layers are the lidar's alone."""
    return None


def d415(ctx: DeviceContext, kind: str) -> D415:
    """The robot's one RealSense D415 (``devices.depth.serial``), made by the first of its streams' drivers and
    shared with the other (a camera is opened by one pipeline at a time)."""
    from atemr.io.devices.realsense import D415

    camera = ctx.shared.get("realsense")
    if camera is None:
        camera = ctx.shared["realsense"] = D415(now=ctx.now, serial=ctx.config.devices.depth.serial,
                                                config_path=f"devices.{kind}.driver")
    assert isinstance(camera, D415)
    return camera


@depth_drivers.register("realsense")
def realsense(ctx: DeviceContext) -> Device[Any]:
    """Intel RealSense D415 over USB through pyrealsense2 (`atemr.io.devices.realsense`; the realsense extra)."""
    cfg = ctx.config.devices.depth
    return d415(ctx, "depth").depth_stream(cfg, depth_mount(cfg))


@camera_drivers.register("realsense")
def realsense_camera(ctx: DeviceContext) -> Device[Any]:
    """The D415's colour stream as the front camera, from the same pipeline as its depth
    (`atemr.io.devices.realsense`; the realsense extra)."""
    return d415(ctx, "camera").colour_stream(ctx.config.devices.camera)


@lidar_drivers.register("rplidar")
def rplidar(ctx: DeviceContext) -> Device[Any]:
    """SLAMTEC RPLidar A2M8 on USB serial (`atemr.io.devices.rplidar`)."""
    from atemr.io.devices.rplidar import RplidarDriver

    return RplidarDriver.from_config(ctx.config.devices.lidar, now=ctx.now)


@imu_drivers.register("wt901")
def wt901(ctx: DeviceContext) -> Device[Any]:
    """WitMotion WT901 on USB serial (`atemr.io.devices.wt901`)."""
    from atemr.io.devices.wt901 import Wt901Driver

    return Wt901Driver.from_config(ctx.config.devices.imu, now=ctx.now)


@camera_drivers.register("opencv")
def opencv_camera(ctx: DeviceContext) -> Device[Any]:
    """Anything OpenCV opens: V4L2, a file, a URL (`atemr.io.devices.camera`; the ``camera`` extra)."""
    from atemr.io.devices.camera import OpenCvCamera

    return OpenCvCamera.from_config(ctx.config.devices.camera, now=ctx.now)


def driver_name(config: Config, kind: str) -> str:
    """The driver that runs ``kind`` in this configuration (``auto`` resolved)."""
    return resolved_driver(config.devices, kind, config.simulation)


def camera_rate_hz(config: Config) -> float:
    """Frames per second the configured camera delivers (the simulator's ``sim.camera_hz`` or the real
    camera's ``devices.camera.fps``): the rate its consumers (the video recorder) sample at."""
    if driver_name(config, "camera") == "sim":
        return config.sim.camera_hz
    return config.devices.camera.fps


def needs_world(config: Config) -> bool:
    """Whether this robot runs the simulated world: in simulation, or when any device is the simulator's
    (a ``sim`` sensor, or motors or a secondary core ``emulated`` in it)."""
    if config.simulation:
        return True
    kinds = ("lidar", "imu", "camera", "depth", "motors", "secondary")
    return any(driver_name(config, kind) in SIMULATED_DRIVERS for kind in kinds)


def build_device(ctx: DeviceContext, kind: str) -> Device[Any] | None:
    """The device ``kind`` with its configured driver; an unknown driver is a `ConfigError` naming the key."""
    name = driver_name(ctx.config, kind)
    registry = REGISTRIES[kind]
    if name not in registry:
        raise ConfigError(registry.unknown_message(name), path=f"devices.{kind}.driver")
    return registry.get(name)(ctx)


def build_devices(ctx: DeviceContext) -> Devices:
    """Every sensor of the robot described by ``ctx.config``."""
    lidar, imu = build_device(ctx, "lidar"), build_device(ctx, "imu")
    if lidar is None or imu is None:
        raise ConfigError("the robot needs a lidar and an IMU", path="devices")
    return Devices(lidar=lidar, imu=imu, camera=build_device(ctx, "camera"), depth=build_device(ctx, "depth"))
