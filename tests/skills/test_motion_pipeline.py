"""The safe-motion pipeline in closed loop against a tiny kinematic world: the thesis behaviours.

The double is deliberately simple: perfect wheels (the commanded wheel speeds are the actual ones),
circles and wall segments seen by an analytic 360-beam lidar 0.10 m ahead of the axle, rectangular
drop zones under the three IR sensors. Time is a plain float advanced 20 ms per tick (50 Hz).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.config import Config
from atemr.errors import ConfigError
from atemr.msgs import CliffReadings, LaserScan, Pose2D, Twist, WheelSpeeds
from atemr.scheduler import Scheduler
from atemr.skills.cliff import CliffGeometry
from atemr.skills.diff_drive import DiffDrive, arc_step
from atemr.skills.motion_pipeline import (
    ControlInputs,
    ControlResult,
    MotionControl,
    MotionPipeline,
    PipelineSettings,
    TimedClearance,
    TimedTwist,
)
from atemr.skills.ramp import Clearance, MotionLimits

DT = 0.02
FOOTPRINT_M = 0.25
LIDAR = Pose2D(0.10, 0.0, 0.0)
N_BEAMS = 400  # 0.9° resolution, as KAY's lidar
INC = 2 * math.pi / N_BEAMS


@dataclass
class Disc:
    x: float
    y: float
    r: float
    vx: float = 0.0
    vy: float = 0.0


@dataclass
class World:
    """Robot pose, obstacles, drop zones; advances with the wheel speeds the pipeline commands."""

    pose: Pose2D = field(default_factory=Pose2D)
    discs: list[Disc] = field(default_factory=list)
    walls_x: list[float] = field(default_factory=list)  # infinite walls x = c (in front of the start)
    lines: list[tuple[float, float, float]] = field(default_factory=list)  # infinite walls a·x + b·y = c, a²+b²=1
    drops: list[tuple[float, float, float, float]] = field(default_factory=list)  # xmin, xmax, ymin, ymax
    t: float = 0.0
    drive: DiffDrive = field(default_factory=DiffDrive)
    collided: bool = False

    def scan(self) -> LaserScan:
        p = self.pose
        ox = p.x_m + LIDAR.x_m * math.cos(p.yaw_rad)
        oy = p.y_m + LIDAR.x_m * math.sin(p.yaw_rad)
        a = p.yaw_rad + (-math.pi + INC * np.arange(N_BEAMS))
        dx, dy = np.cos(a), np.sin(a)
        best = np.full(N_BEAMS, np.inf)
        for d in self.discs:
            fx, fy = ox - d.x, oy - d.y
            b = fx * dx + fy * dy
            c = fx * fx + fy * fy - d.r * d.r
            disc = b * b - c
            with np.errstate(invalid="ignore"):
                hit = -b - np.sqrt(disc)
            best = np.where((disc >= 0) & (hit > 0), np.minimum(best, hit), best)
        for wx in self.walls_x:
            with np.errstate(divide="ignore", invalid="ignore"):
                hit = (wx - ox) / dx
            best = np.where(hit > 0, np.minimum(best, hit), best)
        for a_, b_, c_ in self.lines:
            with np.errstate(divide="ignore", invalid="ignore"):
                hit = (c_ - a_ * ox - b_ * oy) / (a_ * dx + b_ * dy)
            best = np.where(hit > 0, np.minimum(best, hit), best)
        ranges = np.where(best > 8.0, np.inf, best)
        return LaserScan(self.t, ranges, -math.pi, INC, 0.15, 8.0, LIDAR)

    def cliff(self) -> CliffReadings:
        g = CliffGeometry()
        out = []
        c, s = math.cos(self.pose.yaw_rad), math.sin(self.pose.yaw_rad)
        for mx, my in (g.front_left_xy, g.front_right_xy, g.rear_xy):
            x = self.pose.x_m + c * mx - s * my
            y = self.pose.y_m + s * mx + c * my
            over = any(x0 <= x <= x1 and y0 <= y <= y1 for x0, x1, y0, y1 in self.drops)
            out.append(math.inf if over else 0.06)
        return CliffReadings(self.t, *out)

    def clearance(self) -> float:
        """Gap between the footprint and the nearest obstacle (negative: overlapping)."""
        gaps = [math.hypot(self.pose.x_m - d.x, self.pose.y_m - d.y) - d.r - FOOTPRINT_M for d in self.discs]
        gaps += [abs(wx - self.pose.x_m) - FOOTPRINT_M for wx in self.walls_x]
        gaps += [abs(a * self.pose.x_m + b * self.pose.y_m - c) - FOOTPRINT_M for a, b, c in self.lines]
        return min(gaps, default=math.inf)

    def step(self, result: ControlResult) -> None:
        v, w = self.drive.twist(result.wheels.left_radps, result.wheels.right_radps)
        x, y, th = arc_step(self.pose.x_m, self.pose.y_m, self.pose.yaw_rad, v, w, dt_s=DT)
        self.pose = Pose2D(float(x), float(y), float(th))
        for d in self.discs:
            d.x += d.vx * DT
            d.y += d.vy * DT
        self.t = round(self.t + DT, 9)
        self.collided |= self.clearance() < 0


def centre_distance_to_wall(world: World) -> float:
    return world.walls_x[0] - world.pose.x_m


class Loop:
    """Ticks pipeline and world together; the joystick is re-sent every tick unless ``joy_until``.

    ``scan_every``: a new scan every that many ticks (5: a 10 Hz lidar under the 50 Hz control loop).
    """

    def __init__(self, world: World, pipeline: MotionPipeline | None = None, scan_every: int = 1, **inputs) -> None:
        self.world = world
        self.pipeline = pipeline or MotionPipeline()
        self.inputs = inputs
        self.scan_every = scan_every
        self.log: list[tuple[float, Pose2D, ControlResult]] = []
        self._ticks = 0
        self._scan: LaserScan | None = None

    def run(self, seconds: float, joy: Twist | None = None, joy_until: float = math.inf, **change) -> ControlResult:
        self.inputs.update(change)
        result = None
        for _ in range(round(seconds / DT)):
            w = self.world
            joystick = None
            if joy is not None:
                joystick = TimedTwist(joy, min(w.t, joy_until))
            if self._scan is None or self._ticks % self.scan_every == 0:
                self._scan = w.scan()
            self._ticks += 1
            result = self.pipeline.tick(
                ControlInputs(now=w.t, scan=self._scan, cliff=w.cliff(), joystick=joystick, **self.inputs)
            )
            self.log.append((w.t, w.pose, result))
            w.step(result)
        assert result is not None
        return result


# ---- scenarios ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("scan_every", [1, 5])
def test_slows_near_a_wall_and_stops_at_the_stop_distance(scan_every):
    world = World(walls_x=[3.0])
    # this world's wheels are perfect (no lag: the base stops the tick zero is commanded), so no braking distance
    loop = Loop(world, MotionPipeline({"brake_latency_s": 0.0}), scan_every=scan_every)
    loop.run(8.0, joy=Twist(0.8, 0.0))
    # the lidar sees the wall from 0.10 m ahead of the axle: the stop distance is measured from the base origin;
    # with a 10 Hz lidar the scan's clearance is aged by the distance driven since it was taken
    distance = centre_distance_to_wall(world)
    assert 0.28 - 0.35 * DT - 1e-9 <= distance < 0.28
    assert not world.collided
    last = loop.log[-1][2]
    assert last.emergency and last.twist.is_zero and last.source == "joystick"
    # inside the slow zone nothing faster than 0.35 m/s once the ramp has brought the speed down
    for _, pose, r in loop.log:
        gap = world.walls_x[0] - pose.x_m
        if gap < 0.56 - 0.8 * 0.45:  # 0.8 → 0.35 m/s at 1 m/s² takes 0.45 s
            assert r.twist.linear_mps <= 0.35 + 1e-9
        if gap < 0.56:
            assert r.slow or r.emergency
    assert max(r.twist.linear_mps for _, _, r in loop.log) == pytest.approx(0.8)


class LaggingWorld(World):
    """Wheels like the RMD motors behind the driver: a command reaches them one control period later, then
    they follow it with first-order lag (time constant ``tau``)."""

    tau: float = 0.08

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._pending = WheelSpeeds()
        self._wheels = WheelSpeeds()

    def step(self, result: ControlResult) -> None:
        decay = math.exp(-DT / self.tau)
        target, self._pending = self._pending, result.wheels
        self._wheels = WheelSpeeds(target.left_radps + (self._wheels.left_radps - target.left_radps) * decay,
                                   target.right_radps + (self._wheels.right_radps - target.right_radps) * decay)
        lagged = dataclasses.replace(result, wheels=self._wheels)
        super().step(lagged)


@pytest.mark.parametrize("scan_every", [1, 5])
@pytest.mark.parametrize("speed", [0.2, 0.3, 0.35])
def test_the_stop_zone_leaves_room_for_the_motors_to_brake(scan_every, speed):
    # with lagging motors and the default brake latency the base comes to rest at or beyond the stop distance
    world = LaggingWorld(walls_x=[1.5])
    loop = Loop(world, scan_every=scan_every)
    loop.run(8.0, joy=Twist(speed, 0.0))
    distance = centre_distance_to_wall(world)
    assert loop.log[-1][2].emergency and not world.collided
    assert 0.28 - 1e-9 <= distance <= 0.28 + speed * (MotionLimits().brake_latency_s + DT) + 0.01, distance
    # the same motors without the anticipation drift into the stop zone towards the footprint
    world = LaggingWorld(walls_x=[1.5])
    loop = Loop(world, MotionPipeline({"brake_latency_s": 0.0}), scan_every=scan_every)
    loop.run(8.0, joy=Twist(speed, 0.0))
    assert centre_distance_to_wall(world) < 0.28 - speed * 0.05


def test_a_lagging_base_stopped_early_stays_stopped_while_the_wall_is_there():
    world = LaggingWorld(walls_x=[2.0])
    loop = Loop(world)
    loop.run(8.0, joy=Twist(0.35, 0.0))
    stopped_at = world.pose.x_m
    loop.run(6.0, joy=Twist(0.35, 0.0))  # the operator keeps pushing: no creeping on every 2 s
    assert world.pose.x_m == pytest.approx(stopped_at, abs=1e-6)
    assert all(r.emergency for _, _, r in loop.log[-300:])


def test_stop_zone_resumes_two_seconds_after_the_obstacle_leaves():
    box = Disc(2.0, 0.0, 0.2)
    world = World(discs=[box])
    loop = Loop(world)
    loop.run(6.0, joy=Twist(0.3, 0.0))
    assert loop.log[-1][2].emergency and world.clearance() > 0
    stopped_at = world.pose.x_m
    box.y = 10.0  # the obstacle leaves
    left_at = world.t
    loop.run(3.0, joy=Twist(0.3, 0.0))
    moving = [(t, r) for t, _, r in loop.log if t >= left_at and r.twist.linear_mps > 0]
    assert moving, "never resumed"
    first_move = moving[0][0]
    assert first_move == pytest.approx(left_at + 2.0, abs=DT + 1e-9)
    for t, pose, r in loop.log:
        if left_at <= t < first_move:
            assert r.emergency and pose.x_m == pytest.approx(stopped_at)
    assert world.pose.x_m > stopped_at + 0.1


def test_idle_after_eight_seconds_without_a_command():
    loop = Loop(World())
    loop.run(7.9, joy=Twist(0.0, 0.0))
    assert not loop.log[-1][2].idle
    loop.run(0.2, joy=Twist(0.0, 0.0))
    assert loop.log[-1][2].idle
    r = loop.run(0.04, joy=Twist(0.2, 0.0))
    assert not r.idle


def test_a_lost_joystick_stops_the_base_within_half_a_second():
    world = World()
    loop = Loop(world)
    loop.run(2.0, joy=Twist(0.5, 0.2))
    lost_at = loop.world.t - DT  # the last command was stamped on the last tick
    loop.run(1.0, joy=Twist(0.5, 0.2), joy_until=lost_at)
    for t, _, r in loop.log:
        if lost_at < t < lost_at + 0.5 - 1e-9:
            assert r.twist.linear_mps == pytest.approx(0.5)
        if t >= lost_at + 0.5 - 1e-9:
            assert r.wheels.left_radps == 0.0 and r.wheels.right_radps == 0.0
            assert r.watchdog and r.source is None


def test_a_drop_zone_stops_motion_towards_it_at_once_and_backing_off_works():
    world = World(drops=[(1.5, 5.0, -5.0, 5.0)])  # stairs down beyond x = 1.5
    loop = Loop(world)
    loop.run(8.0, joy=Twist(0.4, 0.0))
    r = loop.log[-1][2]
    assert r.cliff_stop and r.twist.is_zero and r.cliff_drops[:2] == (True, True)
    # the front sensors (0.20 m ahead of the axle) stopped within one tick's travel past the edge
    assert 1.5 - 0.20 <= world.pose.x_m <= 1.5 - 0.20 + 0.4 * DT + 1e-9
    before = world.pose.x_m
    loop.run(1.0, joy=Twist(-0.2, 0.0))
    assert world.pose.x_m < before - 0.05 and not loop.log[-1][2].cliff_stop


@pytest.mark.parametrize(
    ("start", "velocity", "away"),
    [
        ((1.8, 0.0), (-0.12, 0.0), (-1.0, 0.0)),  # walks up from the front: back off
        ((-1.8, 0.05), (0.12, 0.0), (1.0, 0.0)),  # from behind: drive off forward
        ((0.0, 1.8), (0.0, -0.12), (0.0, -1.0)),  # from the left: move off to the right
    ],
)
def test_awareness_idle_base_moves_away_from_an_approaching_obstacle(start, velocity, away):
    world = World()
    loop = Loop(world, awareness=True, scan_every=5)
    loop.run(9.0)  # no operator: idle after 8 s, nothing near → the IDLE engine holds still
    assert loop.log[-1][2].idle and world.pose == Pose2D()
    person = Disc(*start, 0.2, *velocity)
    world.discs.append(person)
    loop.run(14.0)
    moved = world.pose.x_m * away[0] + world.pose.y_m * away[1]
    assert moved > 0.4, f"did not move away: {world.pose}"
    assert not world.collided
    assert {r.source for _, _, r in loop.log[-500:]} == {"reactive"}
    # without awareness the person walks into the base, which does not move
    world2 = World(discs=[Disc(*start, 0.2, *velocity)])
    loop2 = Loop(world2, awareness=False, scan_every=5)
    loop2.run(23.0)
    assert world2.pose == Pose2D() and world2.collided


@pytest.mark.parametrize("offset_m", [-0.12, 0.2])
def test_awareness_steers_a_manually_driven_base_round_an_obstacle(offset_m):
    # a pillar a little to one side of the path; the operator only pushes forward (thesis 4.6 video (v))
    pillar = Disc(2.5, offset_m, 0.15)
    world = World(discs=[pillar])
    loop = Loop(world, awareness=True, scan_every=5)
    loop.run(16.0, joy=Twist(0.26, 0.0))
    # the pillar ended up behind the base, which never touched it nor needed the stop zone
    p = world.pose
    ahead = (pillar.x - p.x_m) * math.cos(p.yaw_rad) + (pillar.y - p.y_m) * math.sin(p.yaw_rad)
    assert ahead < -0.5, f"did not get past the pillar: {p}"
    assert not world.collided
    assert not any(r.emergency for _, _, r in loop.log)
    assert max(abs(r.twist.linear_mps) for _, _, r in loop.log) <= 0.26 + 1e-9
    turned = [r.twist.angular_radps for _, _, r in loop.log]
    # it turned away from the side the pillar is on
    assert (max(turned) > 0.3) if offset_m < 0 else (min(turned) < -0.3)
    # without awareness the base drives straight at it and the stop zone ends the run
    world2 = World(discs=[Disc(2.5, offset_m, 0.15)])
    loop2 = Loop(world2, awareness=False, scan_every=5)
    loop2.run(12.0, joy=Twist(0.26, 0.0))
    assert world2.pose.x_m < 2.5 and loop2.log[-1][2].emergency and not world2.collided


@pytest.mark.parametrize("side", [1, -1])
def test_awareness_steers_a_base_driven_at_a_slanted_wall_clear_of_it(side):
    # a wall crossing the path 3 m ahead at 40°, the operator only pushes forward
    angle = math.radians(40.0) * side
    a, b = math.sin(angle), -math.cos(angle)  # the wall's unit normal; it runs along (cos, sin) through (3, 0)
    wall = (a, b, a * 3.0)
    world = World(lines=[wall])
    loop = Loop(world, awareness=True, scan_every=5)
    loop.run(25.0, joy=Twist(0.26, 0.0))
    assert not world.collided and not any(r.emergency for _, _, r in loop.log)
    # it turned at least parallel to the wall (away from it, never into it), kept clear and kept going
    assert side * world.pose.yaw_rad > abs(angle) - math.radians(10.0), world.pose
    assert side * world.pose.yaw_rad < math.pi / 2, world.pose
    assert abs(a * world.pose.x_m + b * world.pose.y_m - wall[2]) > 0.5
    assert math.hypot(world.pose.x_m, world.pose.y_m) > 4.0
    # without awareness it drives into the stop zone and stays there
    world2 = World(lines=[wall])
    loop2 = Loop(world2, awareness=False, scan_every=5)
    loop2.run(16.0, joy=Twist(0.26, 0.0))
    assert loop2.log[-1][2].emergency and not world2.collided


# ---- the pipeline's own rules ----------------------------------------------------------------------


def tick(p: MotionPipeline, now: float, **kw) -> ControlResult:
    w = World(t=now)
    return p.tick(ControlInputs(now=now, scan=w.scan(), cliff=w.cliff(), **kw))


def test_mode_decides_between_joystick_and_navigation():
    p = MotionPipeline()
    joy = TimedTwist(Twist(0.2, 0.0), 0.0)
    nav = TimedTwist(Twist(0.4, 0.0), 0.0)
    assert tick(p, 0.0, joystick=joy, navigation=nav, mode="MANUAL").source == "joystick"
    assert tick(p, 0.02, joystick=joy, navigation=nav, mode="AUTO").source == "navigation"
    agent = TimedTwist(Twist(0.0, 0.5), 0.02)
    assert tick(p, 0.04, joystick=joy, navigation=nav, agent=agent, mode="AUTO").source == "agent"
    assert tick(p, 0.06, joystick=joy, navigation=nav, agent=agent, mode="MANUAL").source == "joystick"


def test_safety_stop_bypasses_the_ramp():
    p = MotionPipeline()
    for k in range(100):
        r = tick(p, k * DT, joystick=TimedTwist(Twist(0.5, 0.0), k * DT))
    assert r.twist.linear_mps == pytest.approx(0.5)
    r = tick(p, 2.0, joystick=TimedTwist(Twist(0.5, 0.0), 2.0), safety_stop=True)
    assert r.safety_stop and r.source == "safety_stop" and r.twist.is_zero
    r = tick(p, 2.02, joystick=TimedTwist(Twist(0.5, 0.0), 2.02))
    assert r.twist.linear_mps == pytest.approx(0.02)  # ramps up again from zero


def test_stale_scan_means_blind_slow_driving():
    p = MotionPipeline()
    old = World(t=0.0).scan()
    for k in range(200):
        r = p.tick(ControlInputs(now=1.0 + k * DT, scan=old, cliff=CliffReadings(1.0 + k * DT, 0.06, 0.06, 0.06),
                                 joystick=TimedTwist(Twist(1.0, 0.0), 1.0 + k * DT), awareness=True))
    assert r.blind and r.slow and r.twist.linear_mps == pytest.approx(0.35) and r.reactive is None


def test_limits_change_at_run_time_and_a_rejected_value_keeps_the_old():
    p = MotionPipeline()
    tick(p, 0.0, limits={"max_linear_mps": 0.5})
    assert p.limits.max_linear_mps == 0.5
    with pytest.raises(ConfigError, match="max_linear_mps"):
        tick(p, 0.02, limits={"max_linear_mps": 5.0})
    assert p.limits.max_linear_mps == 0.5
    assert p.set_limits(MotionLimits(max_linear_mps=1.0)).max_linear_mps == 1.0
    with pytest.raises(ConfigError, match="mode"):
        tick(p, 0.04, mode="DRIVE")
    with pytest.raises(ConfigError, match="finite time"):
        p.tick(ControlInputs(now=math.nan))
    with pytest.raises(ConfigError, match="scan_max_age_s"):
        PipelineSettings(scan_max_age_s=0.0)


def test_telemetry_is_json_ready():
    import json

    r = tick(MotionPipeline(), 0.0, joystick=TimedTwist(Twist(0.1, 0.0), 0.0))
    data = json.loads(json.dumps(r.telemetry()))
    assert data["source"] == "joystick" and set(data["hex_m"]) == {"FR", "FL", "LC", "RL", "RR", "RC"}
    assert data["clearance_m"] == {"front": None, "rear": None, "side": None}


def test_motion_control_component_on_the_scheduler():
    clock = SimClock()
    sent: list[WheelSpeeds] = []
    world = World()

    def read(now: float) -> ControlInputs:
        world.t = now
        return ControlInputs(now=now, scan=world.scan(), cliff=world.cliff(),
                             joystick=TimedTwist(Twist(0.3, 0.0), now) if now < 1.0 else None)

    control = MotionControl(MotionPipeline(Config().motion), read, sent.append)
    sched = Scheduler(clock)
    sched.add(control, 50.0)
    sched.run(duration=2.0)
    assert len(sent) >= 100
    assert max(w.left_radps for w in sent) == pytest.approx(0.3 / 0.085)
    assert sent[-1] == WheelSpeeds(0.0, 0.0) and control.last is not None and control.last.watchdog
    control.shutdown()
    assert sent[-1] == WheelSpeeds()


def test_motion_control_commands_zero_when_the_tick_fails():
    sent: list[WheelSpeeds] = []
    control = MotionControl(MotionPipeline(), lambda now: ControlInputs(now=now, mode="DRIVE"), sent.append)
    with pytest.raises(ConfigError):
        control.tick(0.0)
    assert sent == [WheelSpeeds()]


# ---- the depth layer's clearances (issue 24) -------------------------------------------------------------------


def run_with_depth(world: World, pipeline: MotionPipeline, edge_x: float, seconds: float,
                   depth_age_limit: float = math.inf) -> list[tuple[Pose2D, ControlResult]]:
    """Drive forward with the joystick; a 10 Hz depth layer reports a table top's edge at ``edge_x`` ahead
    (the lidar, 0.2 m up, sees nothing of it) until ``depth_age_limit``, then goes silent."""
    log = []
    depth = None
    for tick in range(round(seconds / DT)):
        if tick % 5 == 0 and world.t < depth_age_limit:
            depth = TimedClearance(Clearance(front_m=edge_x - world.pose.x_m), world.t)
        result = pipeline.tick(ControlInputs(now=world.t, scan=world.scan(), cliff=world.cliff(),
                                             joystick=TimedTwist(Twist(0.8, 0.0), world.t), depth_clearance=depth))
        log.append((world.pose, result))
        world.step(result)
    return log


def test_a_table_top_the_depth_layer_sees_stops_the_base_as_a_wall_does():
    world = World()  # the lidar sees nothing at all
    log = run_with_depth(world, MotionPipeline({"brake_latency_s": 0.0}), edge_x=3.0, seconds=8.0)
    gap = 3.0 - world.pose.x_m
    assert 0.28 - 0.35 * DT * 5 - 1e-9 <= gap < 0.28  # aged by the travel since the frame, as the scan is
    last = log[-1][1]
    assert last.emergency and last.twist.is_zero
    assert last.clearance is not None and last.clearance.front_m < 0.28
    assert all(r.slow or r.emergency for pose, r in log if 3.0 - pose.x_m < 0.56)


def test_a_stale_depth_clearance_is_ignored():
    world = World()
    run_with_depth(world, MotionPipeline({"brake_latency_s": 0.0}), edge_x=3.0, seconds=6.0, depth_age_limit=0.5)
    assert world.pose.x_m > 3.0  # after the camera went silent nothing held the base back
