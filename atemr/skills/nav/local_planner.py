"""Local planner: trajectory rollout (the dynamic window), all samples at once.

Each tick: target velocities (v, ω) are sampled over the whole speed range; each is rolled out as the
base would drive it — from the current velocity towards the target at the acceleration limits, then
held (TrajectoryPlanner's model, so a sharp turn from rest is planned as it will really happen) — over
``sim_time_s`` at ``sim_step_s``: (targets × steps) arrays, filled by compiled loops. Each trajectory is checked
against the costmap's clearance (any pose within the inscribed radius of an obstacle rules it out, and so
does any pose with an obstacle in the speed ramp's stop cone ahead: a path the safety layer would end in an
emergency stop is no path) and scored (lower is better):

* ``path_weight`` × distance from its end to the global path (stay on the plan),
* ``goal_weight`` × path length still to go from its end (progress),
* ``obstacle_weight`` × the highest inflation cost it crosses / 252 (keep away from walls),
* ``heading_weight`` × its final heading error to the carrot, a path point ``lookahead_m`` ahead / π.

Speed is scored by the progress term: every rollout lasts the same ``sim_time_s``, so the path length still to
go from its end falls by ``goal_weight`` × (speed along the path) × ``sim_time_s``; on a clear path the
fastest target wins (DWA's separate velocity bonus would count the same thing twice), and slower ones win
only where the obstacle, path or heading terms say so.

The command is one acceleration step towards the best target, so speed and acceleration limits hold
tick by tick. Speed also falls with the distance left (``v ≤ √(2·a·d)``), so the base can always stop
at the goal. When the path ahead is far to the side or behind, the base first turns on the spot (a round
base may), rather than sweeping a wide arc. The chosen twist goes to the motion pipeline's navigation
input; the chosen trajectory goes to the dashboard.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from atemr.errors import NavigationError
from atemr.msgs import Pose2D, Twist
from atemr.skills.nav.costmap import MAX_NON_OBSTACLE, Costmap

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LocalPlannerParams:
    """Limits, sampling and weights. Limits sit below the speed ramp's (1.0 m/s², 3 rad/s²) so the ramp
    does not distort what was planned; 0.5 m/s is a walking pace for a home."""

    max_linear_mps: float = 0.5
    max_angular_radps: float = 1.2
    linear_accel_mps2: float = 0.8
    angular_accel_radps2: float = 2.5
    control_period_s: float = 0.1
    sim_time_s: float = 1.6
    sim_step_s: float = 0.1
    linear_samples: int = 9
    angular_samples: int = 25
    path_weight: float = 1.2
    goal_weight: float = 1.0
    obstacle_weight: float = 0.4
    heading_weight: float = 0.3
    lookahead_m: float = 0.8
    #: Turn on the spot first when the carrot is farther off the heading than this.
    rotate_threshold_rad: float = 1.0
    #: Reverse speed allowed only to back away from something inside the inscribed radius.
    escape_reverse_mps: float = 0.15
    #: Gain of the in-place rotation (rad/s per rad of error), before the rate and acceleration limits.
    rotate_gain: float = 2.0
    #: Keep obstacles this far from the base within ±60° of the direction it drives: the speed ramp's stop
    #: zone (0.28 m), its braking anticipation at the slow zone's 0.35 m/s (0.04 m), the travel during one
    #: 10 Hz scan (0.035 m) and a grid cell (0.05 m). A path the ramp would end in an emergency stop is no
    #: path (a turn round a door jamb); a 0.8 m doorway still passes (its jambs enter the cone at 0.46 m).
    stop_cone_m: float = 0.40
    #: The motion pipeline's stop zone (`atemr.skills.ramp.MotionLimits`): it halts the base when the nearest
    #: return ahead (behind, reversing) minus speed × ``brake_latency_s`` falls below ``stop_distance_m``, and
    #: holds until the way is clear. A plan it would veto is no plan: speed is capped so the base can brake
    #: in time, to a stop ``stop_margin_m`` short of the zone (`zone_speed_cap`). The assembly copies the
    #: configured values.
    stop_distance_m: float = 0.28
    brake_latency_s: float = 0.12
    stop_margin_m: float = 0.03

    def __post_init__(self) -> None:
        for name in ("max_linear_mps", "max_angular_radps", "linear_accel_mps2", "angular_accel_radps2",
                     "control_period_s", "sim_time_s", "sim_step_s", "lookahead_m", "rotate_threshold_rad",
                     "rotate_gain", "escape_reverse_mps", "stop_cone_m", "brake_latency_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise NavigationError(f"local planner: {name} must be a finite number > 0, got {value!r}")
        for name in ("stop_distance_m", "stop_margin_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise NavigationError(f"local planner: {name} must be a finite number >= 0, got {value!r}")
        if self.linear_samples < 2 or self.angular_samples < 3:
            raise NavigationError("local planner: need at least 2 linear and 3 angular samples")


@dataclass(frozen=True)
class LocalPlan:
    """The chosen command and its rolled-out trajectory ((K+1, 2) world points); ``ok`` False: every
    trajectory was blocked and the command is a stop."""

    twist: Twist
    trajectory: FloatArray
    ok: bool
    candidates: int
    valid: int


def wrap(angle: FloatArray | float) -> FloatArray:
    """Angles wrapped to (−π, π]."""
    a = np.asarray(angle, dtype=np.float64)
    return np.asarray(np.arctan2(np.sin(a), np.cos(a)), dtype=np.float64)


def ramped_rollout(pose: Pose2D, velocity: Twist, v_target: FloatArray, w_target: FloatArray, *, step_s: float,
                   steps: int, linear_accel: float, angular_accel: float
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Poses (x, y, yaw), each (P, steps), when the base goes from ``velocity`` towards each target (v, ω)
    at the acceleration limits and then holds it (TrajectoryPlanner's model): a sharp turn from rest is
    planned as the base would really drive it. Midpoint integration per step (`_rollout_poses`)."""
    v_target = np.ascontiguousarray(v_target, dtype=np.float64)
    w_target = np.ascontiguousarray(w_target, dtype=np.float64)
    if v_target.shape != w_target.shape or v_target.ndim != 1:
        raise NavigationError(f"local planner: {v_target.shape} linear targets for {w_target.shape} angular ones")
    return _rollout_poses((pose.x_m, pose.y_m, pose.yaw_rad), (velocity.linear_mps, velocity.angular_radps),
                          (v_target, w_target), (float(step_s), int(steps)),
                          (float(linear_accel), float(angular_accel)))


def stop_cone_clearance(costmap: Costmap, xs: FloatArray, ys: FloatArray, yaw: FloatArray, *, direction: FloatArray,
                        radius_m: float) -> FloatArray:
    """A cheap stand-in for "is anything within ``radius_m`` inside ±60° of the direction of travel", per pose:
    the clearance at a probe half ``radius_m`` ahead, scaled so that 1 means nothing in that cone.

    An obstacle at distance r ≤ R and bearing |φ| ≤ 60° is within R·√(1 − 1/2 + 1/4) = 0.866·R of a probe at
    R/2 ahead, while one beside the base (φ = 90°) at the inscribed distance is farther: the probe's clearance
    below 0.866·R flags the cone (a little conservative between 60° and 75°). ``direction`` is +1 forward, -1
    reversing, 0 turning on the spot (never flagged: the ramp does not stop a turn)."""
    half = 0.5 * radius_m * direction
    probe = costmap.distance_at(xs + half * np.cos(yaw), ys + half * np.sin(yaw))
    return np.where(direction == 0, np.inf, probe / (math.sqrt(0.75) * radius_m))


def zone_speed_cap(clearance_m: float, params: LocalPlannerParams) -> float:
    """Highest speed towards a return ``clearance_m`` away (from the base origin, in the ramp's sector) at which the
    motion pipeline's stop zone never fires: the room left before the zone and margin must cover the latency
    (a control period plus the ramp's ``brake_latency_s``) and the braking at ``linear_accel_mps2``."""
    room = clearance_m - params.stop_distance_m - params.stop_margin_m
    if room <= 0:
        return 0.0
    if not math.isfinite(room):
        return math.inf
    return min(room / (params.brake_latency_s + params.control_period_s),
               math.sqrt(2 * params.linear_accel_mps2 * room))


def arc_lengths(path: FloatArray) -> FloatArray:
    """Cumulative length along ``path`` (N, 2) at each of its points (0 at the first)."""
    seg = np.hypot(*np.diff(path, axis=0).T) if len(path) > 1 else np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(seg)])


def path_progress(path: FloatArray, x: float, y: float) -> tuple[int, FloatArray]:
    """Index of the path point nearest (x, y) and the cumulative arc length of the path."""
    i = int(np.argmin(np.hypot(path[:, 0] - x, path[:, 1] - y)))
    return i, arc_lengths(path)


class LocalPlanner:
    """Chooses the twist to command from the pose, the current velocity, the global path and the costmap."""

    def __init__(self, costmap: Costmap, params: LocalPlannerParams | None = None) -> None:
        self.costmap = costmap
        self.params = params or LocalPlannerParams()
        load_compiled()

    def targets(self, velocity: Twist, v_cap: float, *, reverse: bool = False) -> tuple[FloatArray, FloatArray]:
        """The sampled target (v, ω) pairs (flattened grid) over the whole speed range, plus the current
        velocity and straight ahead; forward only, unless ``reverse`` (something is inside the inscribed
        radius: backing away may be the way out)."""
        p = self.params
        v_min = -p.escape_reverse_mps if reverse else 0.0
        v_hi = max(v_cap, v_min)
        vs = np.append(np.linspace(v_min, v_hi, p.linear_samples), np.clip(velocity.linear_mps, v_min, v_hi))
        w_max = p.max_angular_radps
        ws = np.append(np.linspace(-w_max, w_max, p.angular_samples),
                       [0.0, float(np.clip(velocity.angular_radps, -w_max, w_max))])
        vv, ww = np.meshgrid(vs, ws, indexing="ij")
        return vv.reshape(-1), ww.reshape(-1)

    def first_command(self, velocity: Twist, v_target: float, w_target: float, dt_s: float) -> Twist:
        """The command for this control period on the way to a target: one acceleration step towards it."""
        p = self.params
        dv = p.linear_accel_mps2 * dt_s
        dw = p.angular_accel_radps2 * dt_s
        v = velocity.linear_mps + float(np.clip(v_target - velocity.linear_mps, -dv, dv))
        w = velocity.angular_radps + float(np.clip(w_target - velocity.angular_radps, -dw, dw))
        return Twist(v, w)

    def _rollout(self, pose: Pose2D, velocity: Twist, vs: FloatArray, ws: FloatArray, horizon_s: float
                 ) -> tuple[FloatArray, FloatArray, FloatArray]:
        p = self.params
        steps = max(round(horizon_s / p.sim_step_s), 1)
        return ramped_rollout(pose, velocity, vs, ws, step_s=p.sim_step_s, steps=steps,
                              linear_accel=p.linear_accel_mps2, angular_accel=p.angular_accel_radps2)

    def rotate(self, yaw_error_rad: float, velocity: Twist, dt_s: float) -> Twist:
        """Turn on the spot towards a heading: proportional, within the rate and acceleration limits, slowing
        so it can stop at the target (ω ≤ √(2·α·|error|)); the linear speed brakes to zero."""
        p = self.params
        target = p.rotate_gain * yaw_error_rad
        cap = min(p.max_angular_radps, math.sqrt(2 * p.angular_accel_radps2 * abs(yaw_error_rad)))
        target = max(-cap, min(cap, target))
        dw = p.angular_accel_radps2 * dt_s
        w = max(velocity.angular_radps - dw, min(velocity.angular_radps + dw, target))
        dv = p.linear_accel_mps2 * dt_s
        v = max(0.0, velocity.linear_mps - dv) if velocity.linear_mps > 0 else min(0.0, velocity.linear_mps + dv)
        return Twist(v, w)

    def compute(self, pose: Pose2D, velocity: Twist, path: FloatArray, goal_xy: tuple[float, float],
                dt_s: float | None = None, *, zone: tuple[float, float] | None = None) -> LocalPlan:
        """The twist that best follows ``path`` (world points, start to goal) from ``pose``.

        ``zone``: the nearest returns (front, rear) as the motion pipeline's stop zone sees them
        (`atemr.skills.hexpattern.HexSectors.nearest_by_direction`); speed either way is capped by
        `zone_speed_cap`, so the plan is one the pipeline will drive (None: no scan, no cap)."""
        p = self.params
        if len(path) == 0:
            raise NavigationError("local planner: empty path")
        dt = p.control_period_s if dt_s is None else min(max(dt_s, 1e-3), 1.0)
        cm = self.costmap
        r_in = cm.params.inscribed_radius_m
        here = np.array([pose.x_m, pose.y_m])
        i_near, s = path_progress(path, pose.x_m, pose.y_m)
        d_goal = math.hypot(goal_xy[0] - pose.x_m, goal_xy[1] - pose.y_m)
        # Carrot: lookahead along the path from the nearest point (the goal at the end).
        i_carrot = int(np.searchsorted(s, s[i_near] + p.lookahead_m))
        carrot = path[min(i_carrot, len(path) - 1)]
        # Turn on the spot first when the path just ahead (a short carrot, so a corner is not cut) is far off.
        near = path[min(int(np.searchsorted(s, s[i_near] + 0.35)), len(path) - 1)]
        heading_err = float(wrap(math.atan2(near[1] - pose.y_m, near[0] - pose.x_m) - pose.yaw_rad))
        clearance_here = float(cm.distance_at(pose.x_m, pose.y_m))
        escaping = clearance_here < r_in  # something is (or will be) too close: get away first, turn later
        if not escaping and abs(heading_err) > p.rotate_threshold_rad and np.hypot(*(near - here)) > 0.05:
            twist = self.rotate(heading_err, velocity, dt)
            traj = np.repeat(here[None, :], 2, axis=0)
            return LocalPlan(twist, traj, True, 1, 1)

        # Slow down for the goal: able to stop there (√(2·a·d)), and creeping over the last decimetres.
        v_cap = min(p.max_linear_mps, math.sqrt(2 * p.linear_accel_mps2 * d_goal), max(0.08, 1.2 * d_goal))
        front_cap, rear_cap = (math.inf, math.inf) if zone is None else (zone_speed_cap(zone[0], p),
                                                                        zone_speed_cap(zone[1], p))
        v_cap = min(v_cap, front_cap)
        vs, ws = self.targets(velocity, v_cap, reverse=escaping)
        vs = np.maximum(vs, -rear_cap)
        xs, ys, th = self._rollout(pose, velocity, vs, ws, p.sim_time_s)
        valid = self._valid(pose, xs, ys, th, vs=vs, clearance_here=clearance_here)
        score = self._score(xs, ys, th, path=path, s=s, i_near=i_near, carrot=carrot)
        score = np.where(valid, score, np.inf)
        n_valid = int(valid.sum())
        if n_valid == 0:
            return LocalPlan(Twist(0.0, 0.0), np.repeat(here[None, :], 2, axis=0), False, len(vs), 0)
        best = int(np.argmin(score))
        traj = np.vstack([here, np.column_stack([xs[best], ys[best]])])
        twist = self.first_command(velocity, float(vs[best]), float(ws[best]), dt)
        twist = Twist(min(max(twist.linear_mps, -rear_cap), front_cap), twist.angular_radps)
        # A stop chosen because every move is ruled out is a blocked robot, not progress.
        moving = abs(twist.linear_mps) > 1e-3 or abs(twist.angular_radps) > 1e-3 or abs(vs[best]) > 1e-3
        return LocalPlan(twist, traj, moving, len(vs), n_valid)

    def _valid(self, pose: Pose2D, xs: FloatArray, ys: FloatArray, th: FloatArray, *, vs: FloatArray,
               clearance_here: float) -> NDArray[np.bool_]:
        """Which rollouts (from ``pose``, at linear speeds ``vs``) are safe to take (`_rollouts_valid` says how)."""
        p, cm = self.params, self.costmap
        r_in = cm.params.inscribed_radius_m
        escaping = clearance_here < r_in
        # From inside the inscribed radius, the clearance from the map may not fall below it (with a margin: the
        # base lags its commands), nor below what it is now.
        hard_floor = min(r_in + 0.05, float(cm.static_distance_at(pose.x_m, pose.y_m))) if escaping else math.inf
        cone_here = float(stop_cone_clearance(cm, np.array([pose.x_m]), np.array([pose.y_m]),
                                              np.array([pose.yaw_rad]), direction=np.array([1.0]),
                                              radius_m=p.stop_cone_m)[0])
        floor = min(r_in, clearance_here)
        valid = np.empty(len(vs), dtype=np.bool_)
        _rollouts_valid(
            (xs, ys, th), np.ascontiguousarray(vs, dtype=np.float64),
            (cm.distance_m, cm.static_distance_m, cm.grid_transform()),
            ((pose.x_m, pose.y_m), (floor, floor - cm.resolution_m, clearance_here, escaping, hard_floor),
             (0.5 * p.stop_cone_m, math.sqrt(0.75) * p.stop_cone_m, min(1.0, cone_here))), valid)
        return valid

    def _score(self, xs: FloatArray, ys: FloatArray, th: FloatArray, *, path: FloatArray, s: FloatArray,
               i_near: int, carrot: FloatArray) -> FloatArray:
        """The cost of each rollout (lower is better): off the path, distance still to go along it, obstacle
        cost on the way, heading off the carrot at the end."""
        p, cm = self.params, self.costmap
        total = float(s[-1])
        obstacle = np.minimum(cm.cost_at(xs, ys).max(axis=1), MAX_NON_OBSTACLE) / MAX_NON_OBSTACLE
        # Path terms against the part of the path ahead (a window of a few metres).
        j1 = int(np.searchsorted(s, s[i_near] + p.lookahead_m + p.max_linear_mps * p.sim_time_s + 0.5))
        local = path[i_near:min(j1, len(path) - 1) + 1]
        s_local = s[i_near:i_near + len(local)]
        ex, ey = xs[:, -1], ys[:, -1]
        d = np.hypot(ex[:, None] - local[None, :, 0], ey[:, None] - local[None, :, 1])
        j = np.argmin(d, axis=1)
        path_dist = d[np.arange(len(j)), j]
        to_go = (total - s_local[j]) + path_dist
        heading = np.abs(wrap(np.arctan2(carrot[1] - ey, carrot[0] - ex) - th[:, -1])) / math.pi
        near_end = np.hypot(carrot[0] - ex, carrot[1] - ey) < 0.05
        heading = np.where(near_end, 0.0, heading)
        return (p.path_weight * path_dist + p.goal_weight * to_go + p.obstacle_weight * obstacle
                + p.heading_weight * heading)

    def evade(self, pose: Pose2D, velocity: Twist, dt_s: float | None = None) -> Twist:
        """While waiting: if something is inside the inscribed radius (a person walked up), the move in the
        window (reverse allowed) that opens the gap most without ever closing it; zero when nothing is close
        or nothing helps. A robot that stands still in someone's way gets walked into."""
        p = self.params
        cm = self.costmap
        dt = p.control_period_s if dt_s is None else min(max(dt_s, 1e-3), 1.0)
        here = float(cm.distance_at(pose.x_m, pose.y_m))
        if here >= cm.params.inscribed_radius_m:
            return Twist(0.0, 0.0)
        vs, ws = self.targets(velocity, 0.3, reverse=True)
        xs, ys, _ = self._rollout(pose, velocity, vs, ws, 1.0)
        clear = cm.distance_at(xs, ys)
        # Never towards a wall: the real clearance stays above the inscribed radius with a margin (the base
        # lags its commands), or, already below it, never falls.
        floor = min(cm.params.inscribed_radius_m + 0.05, float(cm.static_distance_at(pose.x_m, pose.y_m)))
        hard = cm.static_distance_at(xs, ys)
        safe = (clear.min(axis=1) >= here) & (hard.min(axis=1) >= floor)
        gain = np.where(safe, clear[:, -1] - here, -np.inf)
        best = int(np.argmax(gain))
        if gain[best] <= 0.01:
            return Twist(0.0, 0.0)
        return self.first_command(velocity, float(vs[best]), float(ws[best]), dt)


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) the planner's loops when the first planner is
    built, not at its first tick: the calls have the argument types of `LocalPlanner.compute`'s (a test checks
    that a running robot has one compiled version of each loop)."""
    one, grid = np.ones((1, 1)), np.ones((1, 1), dtype=np.float32)
    _rollout_poses((0.0, 0.0, 0.0), (0.0, 0.0), (one[0], one[0]), (0.1, 1), (1.0, 1.0))
    _rollouts_valid((one, one, one), one[0], (grid, grid, (0.0, 0.0, 1.0, 0.0, False, 1.0)),
                    ((0.0, 0.0), (0.0, 0.0, 0.0, False, 0.0), (0.1, 0.2, 1.0)), np.empty(1, dtype=np.bool_))


@njit(cache=True, nogil=True)
def _rollout_poses(start: tuple[float, float, float], velocity: tuple[float, float],  # pragma: no cover  numba
                   targets: tuple[FloatArray, FloatArray], timing: tuple[float, int], accel: tuple[float, float]
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """`ramped_rollout`'s poses, a target at a time: the speed clipped towards the target by the acceleration
    times the step's midpoint time, the yaw and position summed step by step. The numpy version it replaced
    (``numpy_ramped_rollout`` in ``benchmarks/numpy_baselines.py``) made a dozen (targets × steps) arrays; the
    same expressions in the same order (numpy's cumulative sums run from the first term, and so do these), so the
    same bits, which a test holds it to."""
    x0, y0, yaw0 = start
    v0, w0 = velocity
    v_target, w_target = targets
    step_s, steps = timing
    linear_accel, angular_accel = accel
    half_step = step_s / 2
    n = v_target.shape[0]
    xs = np.empty((n, steps))
    ys = np.empty((n, steps))
    th = np.empty((n, steps))
    for i in range(n):
        sum_w = sum_x = sum_y = 0.0
        for k in range(steps):
            t_mid = (k + 0.5) * step_s
            v = v0 + _clip(v_target[i] - v0, -linear_accel * t_mid, linear_accel * t_mid)
            w = w0 + _clip(w_target[i] - w0, -angular_accel * t_mid, angular_accel * t_mid)
            turn = w * step_s
            sum_w = turn if k == 0 else sum_w + turn
            yaw = yaw0 + sum_w
            yaw_mid = yaw - w * half_step
            dx = v * math.cos(yaw_mid) * step_s
            dy = v * math.sin(yaw_mid) * step_s
            sum_x = dx if k == 0 else sum_x + dx
            sum_y = dy if k == 0 else sum_y + dy
            xs[i, k] = x0 + sum_x
            ys[i, k] = y0 + sum_y
            th[i, k] = yaw
    return xs, ys, th


@njit(cache=True, nogil=True)
def _clip(x: float, lo: float, hi: float) -> float:  # pragma: no cover  compiled by numba
    """`np.clip` of one float: the lower bound first, then the upper one; a NaN stays NaN."""
    x = lo if x < lo else x
    return hi if x > hi else x


@njit(cache=True, nogil=True)
def _at(grid: NDArray[np.float32], x: float, y: float,  # pragma: no cover  compiled by numba
        transform: tuple[float, float, float, float, bool, float]) -> float:
    """``grid``'s value at a world point as a float, 0 outside: `Costmap.distance_at`'s lookup, the cell found
    with `OccupancyMap.world_to_cell`'s arithmetic in its order (`Costmap.grid_transform`). The costmap's
    ``_clear_beams`` finds its cells the same way; each module keeps its own copy because numba's cache of a
    compiled function is checked against its own file only, and a loop calling into another module would keep
    running a stale copy after that module changed."""
    ox, oy, c, s, rotated, resolution_m = transform
    dx = x - ox
    dy = y - oy
    if rotated:
        dx, dy = c * dx + s * dy, -s * dx + c * dy
    row = np.floor(dy / resolution_m)  # a float: NaN and huge values fall outside, as numpy's do
    col = np.floor(dx / resolution_m)
    if 0 <= row < grid.shape[0] and 0 <= col < grid.shape[1]:
        return float(grid[int(row), int(col)])
    return 0.0


@njit(cache=True, nogil=True)
def _rollouts_valid(rollouts: tuple[FloatArray, FloatArray, FloatArray], vs: FloatArray,  # pragma: no cover  numba
                    grids: tuple[NDArray[np.float32], NDArray[np.float32],
                                 tuple[float, float, float, float, bool, float]],
                    limits: tuple[tuple[float, float], tuple[float, float, float, bool, float],
                                  tuple[float, float, float]],
                    out: NDArray[np.bool_]) -> None:
    """Which rollouts are safe to take, into ``out``:

    The grids are the costmap's clearance (`Costmap.distance_m`), the map's own (`Costmap.static_distance_m`) and
    their `Costmap.grid_transform`; ``limits`` are the base's position, the clearance limits and the cone's.

    * never inside the inscribed radius (``clearance``: its floor, ``min(inscribed, clearance here)``). Within a
      cell of where the base stands the grid cannot tell better than a cell: a base resting on the edge of the
      inscribed zone reads the next cell a cell closer whichever way it moves, and would never move again (seen
      with a cat lying right behind the robot), so there the floor is a cell lower;
    * from inside it (``escaping``: pushed against something, or something came close), never closer than now
      and ending farther away: the way out, never a creep inwards. Out of a person's way, but never towards a
      wall: the map's own clearance (``grids[1]``) never below ``hard_floor``;
    * never into the speed ramp's stop cone ahead (`stop_cone_clearance`: ``cone`` holds half its radius, the
      clearance that means nothing is in it, and the floor, ``min(1, the cone's clearance here)``): an emergency
      stop is not a way to follow a path. A rollout standing still (v = 0) has no cone.

    The numpy version it replaced (``NumpyLocalPlanner._valid`` in ``benchmarks/numpy_baselines.py``) looked up
    every pose three times over in (targets × steps) arrays; the same expressions in the same order, so the same
    answers, which a test holds it to."""
    xs, ys, th = rollouts
    distance, static, transform = grids
    (px, py), clearance, cone = limits
    floor, floor_first_cell, clearance_here, escaping, hard_floor = clearance
    cone_half, cone_clear, cone_floor = cone
    resolution_m = transform[5]
    steps = xs.shape[1]
    for i in range(xs.shape[0]):
        ok = True
        direction = np.sign(vs[i]) * 1.0
        half = cone_half * direction
        lowest_cone = np.inf
        hard_lowest = np.inf
        clear = 0.0
        for k in range(steps):
            x, y, yaw = xs[i, k], ys[i, k], th[i, k]
            clear = _at(distance, x, y, transform)
            # clear >= floor passes within a cell of the base too (its floor is lower): the distance to the base
            # (a hypot per pose, the loop's dearest step after the cone's cosine and sine) decides only below it
            if clear < floor:
                ok &= clear >= floor_first_cell and math.hypot(x - px, y - py) < resolution_m
            if escaping:
                hard_lowest = min(hard_lowest, _at(static, x, y, transform))
            if direction != 0:  # a rollout standing still has no cone: nothing to look up
                probe = _at(distance, x + half * math.cos(yaw), y + half * math.sin(yaw), transform)
                lowest_cone = min(lowest_cone, probe / cone_clear)
        if escaping:
            ok &= clear > clearance_here
            ok &= hard_lowest >= hard_floor  # the last pose's too: the lowest is no higher
        out[i] = ok & (lowest_cone >= cone_floor)
