"""The simulation: one world, one base on two wheel models, its sensors, and the scheduler components.

Wiring (see `Simulation.attach`): physics ticks at ``physics_hz`` (steps the wheel models, the base and
the moving obstacles from the time elapsed since the last tick), each sensor at its own rate reads the
true state and publishes what the robot would see. Everything runs from the scheduler's injected clock,
and every random source is a child of the one generator given at construction (one child per
subsystem), so switching the camera on or changing the lidar's noise does not change the trajectory,
and the same seed and world give the same ground truth, step for step.

Ground truth (`Simulation.pose`, the ``sim.truth`` component) is for tests, benchmarks and the
dashboard's simulation panel only; the robot sees scans, IMU samples, cliff readings, camera frames and
its wheels' speeds.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from atemr.config import SimConfig
from atemr.errors import ConfigError
from atemr.io.devices.base import Publishes, Subscribers
from atemr.io.sim.base import BaseParams, Collision, DiffDriveBase, MountedWheel, WheelMotor
from atemr.io.sim.camera import Camera, CameraParams
from atemr.io.sim.cliff import CliffParams, CliffSensors
from atemr.io.sim.depth import DepthCamera, DepthCameraParams
from atemr.io.sim.frame_counter import BLOCK_PX, counter_width_px, draw_counter
from atemr.io.sim.imu import Imu, ImuParams
from atemr.io.sim.lidar import Lidar, LidarParams
from atemr.io.sim.movers import Movers
from atemr.io.sim.scene import Contact, Scene
from atemr.io.sim.world import Furniture, World, load_world
from atemr.msgs import CameraMount, CliffReadings, DepthImage, ImuSample, LaserScan, Pose2D
from atemr.scheduler import Scheduler
from atemr.skills.body import KAY, RobotBody

log = logging.getLogger(__name__)

T = TypeVar("T")
R = TypeVar("R")

#: Longest physics step: at the base's 1.6 m/s top speed, 1.6 cm between collision checks.
MAX_STEP_S = 0.01


@dataclass(frozen=True)
class SimParams:
    """Rates and sensor/base models of a simulation (``camera_hz = 0``: no camera; ``depth_hz = 0``: no depth
    camera)."""

    base: BaseParams = field(default_factory=BaseParams)
    lidar: LidarParams = field(default_factory=LidarParams)
    imu: ImuParams = field(default_factory=ImuParams)
    cliff: CliffParams = field(default_factory=CliffParams)
    camera: CameraParams = field(default_factory=CameraParams)
    depth: DepthCameraParams = field(default_factory=DepthCameraParams)
    physics_hz: float = 100.0
    lidar_hz: float = 10.0
    imu_hz: float = 50.0
    cliff_hz: float = 20.0
    camera_hz: float = 0.0
    depth_hz: float = 0.0
    #: Render camera and depth frames only for a consumer (`FrameSource`): the assembled robot's setting, where
    #: consumers register; the bare simulator renders every frame.
    frames_on_demand: bool = False
    #: The robot's volume (base, mast, tablet): collisions are checked part by part against what is at each
    #: part's heights. Its base radius is the footprint and must be ``base.footprint_radius_m``.
    body: RobotBody = KAY
    #: Draw each frame's number into the camera image (`atemr.io.sim.frame_counter`).
    camera_counter: bool = False

    def __post_init__(self) -> None:
        if not math.isclose(self.body.footprint_radius_m, self.base.footprint_radius_m):
            raise ConfigError(f"the body's base radius ({self.body.footprint_radius_m}) must be the footprint "
                              f"({self.base.footprint_radius_m})", path="sim.body")
        for name in ("physics_hz", "lidar_hz", "imu_hz", "cliff_hz"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 < value <= 10_000):
                raise ConfigError(f"must be within (0, 10000] Hz, got {value!r}", path=f"sim.{name}")
        if not (math.isfinite(self.camera_hz) and 0 <= self.camera_hz <= 120):
            raise ConfigError(f"must be within [0, 120] Hz (0: off), got {self.camera_hz!r}", path="sim.camera_hz")
        if not (math.isfinite(self.depth_hz) and 0 <= self.depth_hz <= 90):
            raise ConfigError(f"must be within [0, 90] Hz (0: off), got {self.depth_hz!r}", path="sim.depth_hz")
        if self.camera_counter and (self.camera.width < counter_width_px() or self.camera.height < BLOCK_PX):
            raise ConfigError(f"the frame counter needs a camera image of at least {counter_width_px()}x{BLOCK_PX} "
                              f"px, got {self.camera.width}x{self.camera.height}", path="sim.camera_counter")


@dataclass(frozen=True)
class Fall:
    """The base drove over a drop zone at time ``t``: it is stuck there (a real robot would be down the stairs)."""

    t: float
    pose: Pose2D
    zone: str


class PeriodicSource(Publishes[T]):
    """A scheduler component that produces one reading per tick (a scan, an IMU sample, the true pose...),
    keeps the latest and tells subscribers (`atemr.io.devices.base.Subscribers`: one that raises is logged
    and does not stop the others).
    """

    def __init__(self, name: str, read: Callable[[float], T]) -> None:
        self.name = name
        self._read = read
        self._out: Subscribers[T] = Subscribers(name)
        #: When the source last ticked (None: never): a simulated device is alive while its source ticks.
        self.last_tick_t: float | None = None

    def tick(self, now: float) -> None:
        self.last_tick_t = now
        self._out.publish(self._read(now))


class FrameSource(PeriodicSource[T]):
    """A simulated camera's frames. On demand (``on_demand``), a tick renders a frame only while a consumer wants
    it: one that subscribed (it takes every frame: the depth obstacle layer), or one registered with `want`
    whose test says so at that tick (the dashboard while someone watches). A consumer that needs a frame at one
    moment (a mission step storing a picture, a recording when its next frame is due) calls `request`.

    A frame costs milliseconds where a scan costs a fraction of one, and a headless run nobody watches renders
    none; without demand the frames are skipped, not the clock: `last_tick_t` still says the camera runs.
    """

    def __init__(self, name: str, read: Callable[[float], T], *, period_s: float, on_demand: bool = False) -> None:
        super().__init__(name, read)
        self.period_s = period_s
        self.on_demand = on_demand
        self._wants: dict[str, Callable[[float], bool]] = {}
        #: Ticks that rendered nothing for want of a consumer.
        self.skipped = 0
        self._rendered_t: float | None = None

    def want(self, consumer: str, wants: Callable[[float], bool]) -> None:
        """Register ``consumer``: ``wants(now)``, on the scheduler's thread at each tick, says whether it needs
        this tick's frame (registering the same name again replaces its test)."""
        self._wants[consumer] = wants

    def wanted(self, now: float) -> bool:
        """Whether a frame is rendered at this tick."""
        return not self.on_demand or self._out.listeners > 0 or any(wants(now) for wants in self._wants.values())

    def request(self, now: float) -> T | None:
        """The newest frame, rendered now (on the caller's thread, which must be the scheduler's) when the last
        one is more than a period old because nobody wanted the frames in between; None before the first
        tick (the camera is not running)."""
        if self.last_tick_t is None:
            return None
        if self._rendered_t is None or now - self._rendered_t > self.period_s * (1 + 1e-9):
            self._publish(now)
        return self.latest

    def tick(self, now: float) -> None:
        self.last_tick_t = now
        if self.wanted(now):
            self._publish(now)
        else:
            self.skipped += 1

    def _publish(self, now: float) -> None:
        self._rendered_t = now
        self._out.publish(self._read(now))


@dataclass(frozen=True)
class TruePose:
    """Ground truth at time ``t``: pose, body speed and turn rate."""

    t: float
    pose: Pose2D
    v_mps: float
    w_radps: float


class Simulation:
    """A world with the robot in it. Build with `build_simulation`; schedule with `attach`."""

    def __init__(
        self,
        world: World,
        left: WheelMotor,
        right: WheelMotor,
        rng: np.random.Generator,
        params: SimParams | None = None,
    ) -> None:
        self.world = world
        self.params = params or SimParams()
        self.left = left
        self.right = right
        base_rng, lidar_rng, imu_rng, cliff_rng, movers_rng = rng.spawn(5)
        self.scene = Scene(world)
        self.movers = Movers(world.movers, self.scene, movers_rng)
        p = self.params
        self.base = DiffDriveBase(left, right, params=p.base, pose=world.start, rng=base_rng,
                                  clearance=self.clearance_at)
        start = self.clearance_at(world.start.x_m, world.start.y_m)
        if start.clearance_m < 0:
            raise ConfigError(f"start pose ({world.start.x_m}, {world.start.y_m}) overlaps {start.what}",
                              file=world.source, path="start")
        self.lidar = Lidar(p.lidar, lidar_rng)
        self.imu = Imu(p.imu, imu_rng)
        self.cliff = CliffSensors(p.cliff, self.scene, cliff_rng)
        self.camera = Camera(p.camera)
        # Spawned after the others, so adding the depth camera changed none of their random streams.
        self.depth_camera = DepthCamera(p.depth, rng.spawn(1)[0])
        self.falls: list[Fall] = []
        self._submitted: deque[tuple[Callable[[], Any], Future[Any]]] = deque()  # deque: thread-safe appends
        self._last_t: float | None = None
        self.t = 0.0
        self.physics = PeriodicSource[TruePose]("sim.physics", self.step_to)
        self.lidar_source = PeriodicSource[LaserScan]("sim.lidar", self.read_lidar)
        self.imu_source = PeriodicSource[ImuSample]("sim.imu", self.read_imu)
        self.cliff_source = PeriodicSource[CliffReadings]("sim.cliff", self.read_cliff)
        self.camera_source = FrameSource[NDArray[np.uint8]](
            "sim.camera", self.render_camera, period_s=_period(p.camera_hz), on_demand=p.frames_on_demand)
        self.depth_source = FrameSource[DepthImage](
            "sim.depth", self.render_depth, period_s=_period(p.depth_hz), on_demand=p.frames_on_demand)

    # -- wiring --------------------------------------------------------------------------------
    def components(self) -> list[tuple[PeriodicSource[Any], float]]:
        """(component, rate) pairs to schedule; the cameras only when their rates are above 0."""
        p = self.params
        out: list[tuple[PeriodicSource[Any], float]] = [
            (self.physics, p.physics_hz), (self.lidar_source, p.lidar_hz), (self.imu_source, p.imu_hz),
            (self.cliff_source, p.cliff_hz),
        ]
        if p.camera_hz > 0:
            out.append((self.camera_source, p.camera_hz))
        if p.depth_hz > 0:
            out.append((self.depth_source, p.depth_hz))
        return out

    def attach(self, scheduler: Scheduler) -> None:
        """Add every component to ``scheduler`` (physics first, so sensors read the state of the same tick)."""
        for component, rate in self.components():
            scheduler.add(component, rate)

    # -- physics -------------------------------------------------------------------------------
    def clearance_at(self, x: float, y: float) -> Contact:
        """Signed clearance of the robot's volume at (x, y) to walls, objects and moving obstacles, each part
        against what is at its heights (people and pets stand on the floor: the base meets them first)."""
        r = self.params.base.footprint_radius_m
        contact = self.scene.body_clearance(x, y, self.params.body)
        for m in self.movers.items:
            gap = math.hypot(m.x_m - x, m.y_m - y) - m.spec.radius_m - r
            if gap < contact.clearance_m:
                contact = Contact(gap, m.name, "base")
        return contact

    def step_to(self, now: float) -> TruePose:
        """Advance the wheels, the base and the moving obstacles to time ``now``.

        A long gap (a real-time run that skipped ticks, a slow physics rate) is cut into sub-steps of at
        most ``MAX_STEP_S``, so the base never moves more than a few centimetres between collision checks
        and cannot pass through a wall.
        """
        self._run_submitted()
        dt = 0.0 if self._last_t is None else now - self._last_t
        start = now - dt
        self._last_t = now
        self.t = now
        if dt > 0:
            n = max(1, math.ceil(dt / MAX_STEP_S - 1e-9))
            for i in range(1, n + 1):
                self._substep(start + dt * i / n, dt / n)
        return TruePose(now, self.base.pose, self.base.v_mps, self.base.w_radps)

    def _substep(self, t: float, dt: float) -> None:
        pose = self.base.pose
        self.movers.step(dt, (pose.x_m, pose.y_m), self.params.base.footprint_radius_m)
        if self.falls:
            self.left.step(dt)
            self.right.step(dt)
            self.base.v_mps = self.base.w_radps = self.base.accel_mps2 = 0.0
            return
        event = self.base.step(t, dt)
        if event is not None:
            log.info("collision at t=%.2f s: the %s hit %s at (%.2f, %.2f)", event.t, event.part or "base",
                     event.what, event.pose.x_m, event.pose.y_m)
        self._check_fall(t)

    def _check_fall(self, now: float) -> None:
        pose = self.base.pose
        if not self.scene.in_drop_zone(pose.x_m, pose.y_m):
            return
        zone = next((z.name for z in self.world.drop_zones
                     if z.contains(np.array([pose.x_m]), np.array([pose.y_m]))[0]), "drop zone")
        self.falls.append(Fall(now, pose, zone))
        log.warning("the robot fell at t=%.2f s: %s at (%.2f, %.2f)", now, zone, pose.x_m, pose.y_m)

    # -- sensors -------------------------------------------------------------------------------
    def read_lidar(self, now: float) -> LaserScan:
        return self.lidar.scan(now, self.base.pose, self.scene, self.movers.centres, self.movers.radii)

    def read_imu(self, now: float) -> ImuSample:
        b = self.base
        return self.imu.sample(now, b.v_mps, b.w_radps, b.accel_mps2)

    def read_cliff(self, now: float) -> CliffReadings:
        return self.cliff.read(now, self.base.pose)

    def render_camera(self, now: float) -> NDArray[np.uint8]:
        image = self.camera.render(self.base.pose, self.scene, self.movers)
        if self.params.camera_counter:
            draw_counter(image, self.camera_source.count + 1)  # the frame's number, from 1
        return image

    def render_depth(self, now: float) -> DepthImage:
        return self.depth_camera.render(now, self.base.pose, self.scene, self.movers)

    # -- truth and events ----------------------------------------------------------------------
    @property
    def pose(self) -> Pose2D:
        """Ground-truth pose (tests, benchmarks, the simulation panel; never the robot's own estimate)."""
        return self.base.pose

    @property
    def odometry(self) -> Pose2D:
        """Pose integrated from the wheels' speeds with encoder noise, from (0, 0, 0) at start."""
        return self.base.odom_pose

    @property
    def collisions(self) -> list[Collision]:
        return self.base.collisions

    # -- run-time interventions (the dashboard's simulation panel) ------------------------------
    def submit(self, action: Callable[[], R]) -> Future[R]:
        """Run ``action`` (e.g. ``lambda: sim.kidnap(pose)``) at the start of the next physics tick.

        For other threads (the web server's): the scene must not change while a sensor is casting rays,
        so interventions wait for the scheduler's thread. The returned future holds the result or the
        exception (a `ConfigError` for a bad pose), for the caller to report.
        """
        future: Future[R] = Future()
        self._submitted.append((action, future))
        return future

    def _run_submitted(self) -> None:
        while self._submitted:
            action, future = self._submitted.popleft()
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(action())
            except Exception as exc:
                future.set_exception(exc)

    def kidnap(self, pose: Pose2D) -> None:
        """Teleport the robot to ``pose`` (tests relocalisation); refused inside an obstacle or off the map."""
        if not all(math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad)):
            raise ConfigError(f"pose must be finite numbers, got {pose}", path="kidnap")
        row, col = self.world.map.world_to_cell(pose.x_m, pose.y_m)
        if not self.world.map.contains(row, col):
            raise ConfigError(f"({pose.x_m:.2f}, {pose.y_m:.2f}) is outside the map", path="kidnap")
        contact = self.clearance_at(pose.x_m, pose.y_m)
        if contact.clearance_m < 0:
            raise ConfigError(f"({pose.x_m:.2f}, {pose.y_m:.2f}) overlaps {contact.what}", path="kidnap")
        self.base.teleport(pose)
        self.falls.clear()

    def drop_obstacle(
        self, x_m: float, y_m: float, *, size_m: float = 0.4, shape: str = "box", name: str | None = None,
        height_m: float = 0.6, color: tuple[int, int, int] = (60, 160, 90),
    ) -> int:
        """Put a box (side ``size_m``) or a cylinder (diameter ``size_m``) at (x, y); returns its id."""
        if not all(math.isfinite(v) for v in (x_m, y_m, size_m, height_m)) or size_m <= 0 or height_m <= 0:
            raise ConfigError("position must be finite and size/height > 0", path="drop obstacle")
        half = size_m / 2
        if shape == "box":
            item = Furniture(name or "dropped box", "box", (x_m - half, y_m - half, x_m + half, y_m + half),
                             height_m, color)
        elif shape == "circle":
            item = Furniture(name or "dropped cylinder", "circle", (x_m, y_m, half), height_m, color)
        else:
            raise ConfigError(f"shape must be 'box' or 'circle', got {shape!r}", path="drop obstacle")
        return self.scene.add_object(item)

    def remove_obstacle(self, object_id: int) -> None:
        """Take away an obstacle placed with `drop_obstacle` (or a piece of furniture, by its id)."""
        self.scene.remove_object(object_id)

    def command_wheels(self, left_radps: float, right_radps: float) -> None:
        """Set the wheels' speed commands, for wheel models with ``set_speed`` (the RMD model).

        On the full robot the motor driver does this over CAN; this shortcut serves the stand-alone
        ``atemr sim`` and tests.
        """
        for wheel, value in ((self.left, left_radps), (self.right, right_radps)):
            setter = getattr(wheel, "set_speed", None)
            if setter is None:
                raise ConfigError(f"wheel {wheel!r} takes no speed commands (no set_speed)", path="command_wheels")
            setter(value)

    def wheel_speeds_for(self, linear_mps: float, angular_radps: float) -> tuple[float, float]:
        """Forward wheel speeds (left, right) in rad/s for a body twist (inverse differential drive)."""
        b = self.params.base
        half = b.track_m / 2
        r = b.wheel_radius_m
        return (linear_mps - angular_radps * half) / r, (linear_mps + angular_radps * half) / r

    def command_twist(self, linear_mps: float, angular_radps: float) -> None:
        """Command a body twist through the wheels (inverse differential-drive kinematics)."""
        self.command_wheels(*self.wheel_speeds_for(linear_mps, angular_radps))


def _period(rate_hz: float) -> float:
    """Seconds between frames at ``rate_hz`` (inf: the camera is off)."""
    return 1.0 / rate_hz if rate_hz > 0 else math.inf


def params_from_config(cfg: SimConfig, body: RobotBody = KAY, depth_mount: CameraMount | None = None) -> SimParams:
    """The simulation parameters named in the robot's configuration (``sim.*``, the robot's ``body`` and where
    its depth camera is mounted); the rest keep defaults."""
    return SimParams(
        base=BaseParams(slip_std=cfg.wheel_slip, odom_noise_std=cfg.odom_noise,
                        footprint_radius_m=body.footprint_radius_m),
        lidar=LidarParams(beams=cfg.lidar_beams, noise_std_m=cfg.lidar_noise_m, dropout_prob=cfg.lidar_dropout,
                          range_max_m=cfg.lidar_range_m, reach_m=max(LidarParams().reach_m, cfg.lidar_range_m)),
        camera=CameraParams(width=cfg.camera_width, height=cfg.camera_height),
        physics_hz=cfg.physics_hz, lidar_hz=cfg.lidar_hz, imu_hz=cfg.imu_hz, cliff_hz=cfg.cliff_hz,
        depth=DepthCameraParams() if depth_mount is None else DepthCameraParams(mount=depth_mount),
        camera_hz=cfg.camera_hz, camera_counter=cfg.camera_counter, depth_hz=cfg.depth_hz, body=body,
    )


def default_wheels(directions: tuple[int, int] = (1, -1)) -> tuple[WheelMotor, WheelMotor]:
    """Two RMD-L-7015 motor models (first-order speed dynamics) mounted as on the robot: the right one
    mirrored (``directions`` as ``motors.left_direction``/``motors.right_direction``)."""
    from atemr.io.motors.model import RmdMotorModel

    return MountedWheel(RmdMotorModel(), directions[0]), MountedWheel(RmdMotorModel(), directions[1])


def build_simulation(
    world: str | Path | World,
    seed: int,
    *,
    params: SimParams | None = None,
    wheels: tuple[WheelMotor, WheelMotor] | None = None,
) -> Simulation:
    """A simulation of ``world`` (a shipped name, a world/map YAML path or a loaded `World`) seeded with ``seed``.

    ``wheels`` default to two `RmdMotorModel`s mounted as on the robot (`default_wheels`). On the full
    robot pass the motor emulators' models, ``(MountedWheel(left_emulator.model, left_direction),
    MountedWheel(right_emulator.model, right_direction))``, and build the emulators with
    ``steps_model=False``: the simulation steps the models, the emulators only answer over CAN.
    """
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}", path="sim.seed")
    params = params or SimParams()
    loaded = world if isinstance(world, World) else load_world(world, robot_radius_m=params.base.footprint_radius_m)
    left, right = wheels if wheels is not None else default_wheels()
    return Simulation(loaded, left, right, np.random.default_rng(seed), params)
