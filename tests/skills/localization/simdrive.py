"""Test helper (not a test module): drive the simulated robot along waypoints and record what it sensed.

The "operator" steers on ground truth with a pure-pursuit rule; the robot's side only gets what the
simulator's sensors and encoders give (scans, IMU samples, noisy odometry), seeded, so every test that
uses a recording is repeatable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from atemr.clock import SimClock
from atemr.io.sim.simulation import SimParams, Simulation, build_simulation
from atemr.msgs import ImuSample, LaserScan, Pose2D
from atemr.scheduler import Scheduler

#: A loop round the coffee table of the studio's living room, clear of furniture by >= 0.3 m.
LIVING_ROOM_LOOP = [(4.3, 2.0), (4.3, 3.55), (2.45, 3.6), (2.45, 1.45), (3.3, 1.6), (4.3, 2.0)]


@dataclass
class Recording:
    """Per scan: the scan, the odometry pose and the true pose when it was taken; IMU samples apart."""

    sim: Simulation
    scans: list[LaserScan] = field(default_factory=list)
    odom: list[Pose2D] = field(default_factory=list)
    truth: list[Pose2D] = field(default_factory=list)
    imu: list[ImuSample] = field(default_factory=list)


class Follower:
    """Pure pursuit over ground truth: a scheduler component commanding the simulated wheels."""

    name = "test.follower"

    def __init__(self, sim: Simulation, waypoints: list[tuple[float, float]], speed_mps: float, laps: int) -> None:
        self.sim, self.route, self.speed = sim, list(waypoints) * laps, speed_mps
        self.i = 0

    @property
    def done(self) -> bool:
        return self.i >= len(self.route)

    def tick(self, now: float) -> None:
        if self.done:
            self.sim.command_twist(0.0, 0.0)
            return
        p = self.sim.pose
        tx, ty = self.route[self.i]
        if math.hypot(tx - p.x_m, ty - p.y_m) < 0.2:
            self.i += 1
            return
        err = math.atan2(ty - p.y_m, tx - p.x_m) - p.yaw_rad
        err = (err + math.pi) % (2 * math.pi) - math.pi
        w = max(-1.2, min(1.2, 2.5 * err))
        v = self.speed * max(0.0, math.cos(err)) ** 4
        self.sim.command_twist(v, w)


def drive(
    waypoints: list[tuple[float, float]] = LIVING_ROOM_LOOP,
    *,
    seed: int = 3,
    speed_mps: float = 0.4,
    laps: int = 1,
    max_s: float = 120.0,
    start: Pose2D | None = None,
    params: SimParams | None = None,
    kidnap: tuple[float, Pose2D] | None = None,
) -> Recording:
    """Drive the route in the studio; stop when it is done (or after ``max_s`` simulated seconds).

    ``kidnap=(t, pose)`` teleports the robot at simulated time ``t`` (whole seconds); it then drives on.
    """
    sim = build_simulation("studio", seed, params=params)
    if start is not None:
        sim.kidnap(start)
    rec = Recording(sim)
    sched = Scheduler(SimClock())
    sim.attach(sched)
    follower = Follower(sim, waypoints, speed_mps, laps)
    sched.add(follower, 10.0)

    def on_scan(scan: LaserScan) -> None:
        rec.scans.append(scan)
        rec.odom.append(sim.odometry)
        rec.truth.append(sim.pose)

    sim.lidar_source.subscribe(on_scan)
    sim.imu_source.subscribe(rec.imu.append)
    t = 0.0
    while not follower.done and t < max_s:
        t += 1.0
        sched.run(until=t)
        if kidnap is not None and kidnap[0] == t:
            sim.kidnap(kidnap[1])
    return rec
