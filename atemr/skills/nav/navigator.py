"""The Navigator: one stateful object the agent's go-to-pose leaf drives every tick (move_base, in small).

``start(goal, now, ...)`` checks the goal (`goal_check`) and plans; then each ``update(now, pose, scan,
localized)`` folds the scan into the costmap (and the moving people and pets the tracker sees, swept
ahead into the predicted layer), replans now and then (and at once when the path ahead is blocked), asks
the local planner for a twist, watches progress, waits (stepping out of the way of whoever comes close)
when there is no path or no safe move, runs recoveries in order when that lasts, and finally turns on the
spot to the goal's heading. It returns a `NavStatus`: RUNNING with
the twist to command (the motion pipeline's navigation input), the distance left, an ETA, the global path
and the local trajectory for the dashboard; SUCCEEDED; or FAILED with the reason (no path, stuck,
localization lost, timeout). Time comes only from ``now``; nothing here reads a clock or does I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.errors import NavigationError
from atemr.io.sim.maps import OccupancyMap
from atemr.msgs import ZERO_TWIST, LaserScan, Pose2D, Twist
from atemr.skills.hexpattern import HEX90, hex_pattern
from atemr.skills.nav.costmap import INSCRIBED, Costmap, CostmapParams
from atemr.skills.nav.global_planner import GlobalPath, GlobalPlanner, PlannerParams
from atemr.skills.nav.goal_check import GoalCheck, check_goal
from atemr.skills.nav.local_planner import LocalPlanner, LocalPlannerParams, arc_lengths, path_progress, wrap
from atemr.skills.nav.moving_obstacles import ObstacleTracker, TrackerParams
from atemr.skills.nav.recovery import RecoveryBehaviour, RecoveryParams
from atemr.skills.nav.route import JOIN_M, Route

FloatArray = NDArray[np.float64]
NavState = Literal["IDLE", "RUNNING", "SUCCEEDED", "FAILED", "CANCELED"]
FailReason = Literal["no path", "stuck", "localization lost", "timeout"]
_EMPTY = np.zeros((0, 2), dtype=np.float64)


@dataclass(frozen=True)
class NavParams:
    """Everything the navigator needs; tolerances are the thesis's (0.25 m, 0.13 rad)."""

    costmap: CostmapParams = field(default_factory=CostmapParams)
    planner: PlannerParams = field(default_factory=PlannerParams)
    local: LocalPlannerParams = field(default_factory=LocalPlannerParams)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)
    tracker: TrackerParams = field(default_factory=TrackerParams)
    #: Predict where moving people and pets are going and keep out of their way (False: present only).
    predict_movers: bool = True
    xy_tolerance_m: float = 0.25
    yaw_tolerance_rad: float = 0.13
    #: Distance at which the approach ends and the final turn begins (inside the tolerance, with margin for
    #: localization error).
    arrive_m: float = 0.1
    #: Plan again this often while following (the obstacle layer changes), and at once when blocked.
    replan_period_s: float = 2.0
    #: How far ahead along the path a blocked cell triggers an immediate replan.
    blocked_lookahead_m: float = 2.0
    #: No local trajectory for this long → stuck (recovery).
    blocked_timeout_s: float = 4.0
    #: No global path: wait this long (planning again every ``path_retry_s``) before each recovery; in a home
    #: the way is usually blocked by someone who will step aside.
    path_wait_s: float = 8.0
    path_retry_s: float = 1.0
    #: The distance left must shrink by ``progress_m`` within this time, or the robot is stuck.
    stuck_timeout_s: float = 10.0
    progress_m: float = 0.15
    #: Progress that proves a recovery worked (the sequence starts again from the first behaviour).
    recovered_after_m: float = 1.0
    localization_timeout_s: float = 10.0
    #: When the recoveries are used up and there is still no path, but the map alone has one, the way is blocked
    #: by what the live scan sees (a pet lying in the only passage, people in a doorway): they move on, so wait
    #: this much longer (stepping out of their way, planning again every ``path_retry_s``) before failing.
    obstacle_wait_s: float = 60.0
    timeout_s: float = 600.0

    def __post_init__(self) -> None:
        if self.arrive_m > self.xy_tolerance_m:
            raise NavigationError(f"navigator: arrive_m ({self.arrive_m}) must not exceed xy_tolerance_m")
        for name in ("xy_tolerance_m", "yaw_tolerance_rad", "arrive_m", "replan_period_s", "blocked_lookahead_m",
                     "blocked_timeout_s", "path_wait_s", "path_retry_s", "stuck_timeout_s", "progress_m",
                     "recovered_after_m", "localization_timeout_s", "obstacle_wait_s", "timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise NavigationError(f"navigator: {name} must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class NavEvent:
    """Something the operator may want to see in the log: a plan, a recovery, the end."""

    t: float
    kind: str
    detail: str = ""


@dataclass(frozen=True)
class NavStatus:
    """One tick's answer. ``twist`` is what to command (zero unless RUNNING)."""

    state: NavState
    twist: Twist = ZERO_TWIST
    phase: str = ""
    distance_left_m: float = math.nan
    eta_s: float = math.nan
    global_path: FloatArray = field(default_factory=lambda: _EMPTY)
    local_trajectory: FloatArray = field(default_factory=lambda: _EMPTY)
    reason: FailReason | None = None
    message: str = ""
    recovery: str | None = None


@dataclass(frozen=True, eq=False)
class NavMap:
    """What a navigator derives from one map (costmap, planners, the map's connected free parts): the heavy part
    of a map change, built by `Navigator.prepare_map` on any thread and handed to one navigator's `set_map`
    (its costmap then takes that navigator's scans: use it once)."""

    occupancy: OccupancyMap
    costmap: Costmap
    planner: GlobalPlanner
    local: LocalPlanner
    static_parts: NDArray[np.int32]


class Navigator:
    """Drives the base to one goal at a time on one map; see the module doc."""

    def __init__(self, occupancy: OccupancyMap, params: NavParams | None = None, *,
                 prepared: NavMap | None = None) -> None:
        self.params = params or NavParams()
        self.events: list[NavEvent] = []
        self.goal: Pose2D | None = None
        self.route: Route | None = None
        self.state: NavState = "IDLE"
        self._route_refused: str | None = None
        self.set_map(occupancy, prepared)
        self._reset()

    # -- set-up --------------------------------------------------------------------------------------------
    @staticmethod
    def prepare_map(occupancy: OccupancyMap, params: NavParams | None = None) -> NavMap:
        """The costmap and planners of ``occupancy`` for a navigator with ``params``; touches no navigator."""
        p = params or NavParams()
        costmap = Costmap(occupancy, p.costmap)
        # Connected parts of the map's own free space (4-connected: the planner cuts no corners), to tell "no
        # path on the map" from "no path past what the scan sees now".
        static_parts, _ = ndimage.label(costmap.static_cost < INSCRIBED)
        return NavMap(occupancy, costmap, GlobalPlanner(costmap, p.planner), LocalPlanner(costmap, p.local),
                      static_parts)

    def set_map(self, occupancy: OccupancyMap, prepared: NavMap | None = None) -> None:
        """Use another map (the operator selected one); cancels nothing, but the next plan uses it. A route being
        driven that the new map rules out fails the goal at the next update, with the reason.

        ``prepared``: ``Navigator.prepare_map(occupancy, params)``, built beforehand: the change is then a swap."""
        if prepared is not None and prepared.occupancy is not occupancy:
            raise ValueError("set_map: the prepared costmap belongs to another map")
        nav_map = prepared if prepared is not None else self.prepare_map(occupancy, self.params)
        self.costmap = nav_map.costmap
        self.planner = nav_map.planner
        self.local = nav_map.local
        self.tracker = ObstacleTracker(self.params.tracker)
        self._path: GlobalPath | None = None
        self._static_parts = nav_map.static_parts
        if self.route is not None and self.state == "RUNNING":
            why = self.route.refusal(self.costmap)
            if why is not None:
                self._route_refused = f"the route does not fit the new map: {why}"

    def _reset(self) -> None:
        self._path = None
        self._route_refused = None
        self._approach: GlobalPath | None = None
        self._t_approach = -math.inf
        self._t_start = 0.0
        self._t_plan = -math.inf
        self._t_last = math.nan
        self._last_scan_t = math.nan
        self._zone: tuple[float, float] | None = None
        self._velocity = ZERO_TWIST
        self._blocked_since: float | None = None
        self._no_path_since: float | None = None
        self._planned = False
        self._lost_since: float | None = None
        self._best_left = math.inf
        self._t_progress = 0.0
        self._recovery_index = 0
        self._recovery: RecoveryBehaviour | None = None
        self._recovery_d_goal = math.inf
        self._last_failure: FailReason = "stuck"
        self._waiting_since: float | None = None
        self._xy_reached = False
        self._creeping = False
        self._trajectory = _EMPTY
        self._final: NavStatus | None = None

    def check(self, goal: Pose2D, *, localized: bool = True, mode: str = "AUTO") -> GoalCheck:
        """Whether ``goal`` would be accepted now (no side effects)."""
        return check_goal(goal, self.costmap, localized=localized, mode=mode,
                          allow_unknown=self.params.planner.allow_unknown)

    def start(self, goal: Pose2D, now: float, *, localized: bool = True, mode: str = "AUTO",
              route: Sequence[Sequence[float]] | None = None) -> GoalCheck:
        """Accept ``goal`` and begin; a refused goal raises `NavigationError` with the reason (the agent turns
        it into its Error state) and leaves the navigator idle.

        ``route``: points ``[x_m, y_m]`` to drive through, in order, on the way to the goal (a `Route`, in
        place of the planner's shortest way); refused when a point is not finite or the map rules it out.
        """
        verdict = self.check(goal, localized=localized, mode=mode)
        planned_route = None
        if verdict.ok and route is not None:
            try:
                planned_route = Route.through(route, goal, self.costmap.resolution_m)
            except ValueError as exc:
                verdict = GoalCheck(False, None, str(exc))
            else:
                why = planned_route.refusal(self.costmap)
                if why is not None:
                    verdict = GoalCheck(False, None, why)
        if not verdict.ok:
            self.events.append(NavEvent(now, "refused", verdict.reason))
            verdict.raise_if_refused()
        self._reset()
        self.goal = goal
        self.route = planned_route
        self.state = "RUNNING"
        self._t_start = now
        self._t_progress = now
        self.events.append(NavEvent(now, "goal", f"({goal.x_m:.2f}, {goal.y_m:.2f}, {goal.yaw_rad:.2f})"
                                    + (f" along a {planned_route.length_m:.2f} m route" if planned_route else "")))
        return verdict

    def cancel(self, now: float | None = None) -> NavStatus:
        """Stop pursuing the goal; the next update returns CANCELED with a zero twist."""
        if self.state == "RUNNING":
            self.state = "CANCELED"
            self._final = NavStatus("CANCELED", phase="canceled", message="goal canceled")
            self.events.append(NavEvent(now if now is not None else self._t_last, "canceled"))
        return self._final or NavStatus(self.state)

    # -- the tick ------------------------------------------------------------------------------------------
    def update(self, now: float, pose: Pose2D, scan: LaserScan | None = None, localized: bool = True,
               velocity: Twist | None = None) -> NavStatus:
        """One navigation tick; ``velocity`` is the measured twist if known (else the last command is used)."""
        if self.state != "RUNNING" or self.goal is None:
            return self._final or NavStatus(self.state)
        p = self.params
        dt = p.local.control_period_s if math.isnan(self._t_last) else min(max(now - self._t_last, 1e-3), 1.0)
        self._t_last = now
        if velocity is not None:
            self._velocity = velocity
        if now - self._t_start > p.timeout_s:
            return self._fail(now, "timeout", f"goal not reached within {p.timeout_s:.0f} s")
        if self._route_refused is not None:
            return self._fail(now, "no path", self._route_refused)
        pose_ok = all(math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad))
        if not (localized and pose_ok):
            if self._lost_since is None:
                self._lost_since = now
                self.events.append(NavEvent(now, "waiting", "localization lost: stopped"))
            if now - self._lost_since > p.localization_timeout_s:
                return self._fail(now, "localization lost",
                                  f"not localized for {p.localization_timeout_s:.0f} s")
            return self._running(ZERO_TWIST, "waiting for localization")
        if self._lost_since is not None:
            self.events.append(NavEvent(now, "localized", "going on"))
            self._lost_since = None
            self._t_progress = now
            self._t_plan = -math.inf
        if scan is not None and scan.t != self._last_scan_t:
            self.costmap.update_from_scan(scan, pose)
            self._last_scan_t = scan.t
            # What the motion pipeline's stop zone will judge the next commands by (nearest return ahead, behind).
            front, rear, _ = hex_pattern(scan, HEX90).nearest_by_direction()
            self._zone = (front, rear)
            if p.predict_movers:
                self.tracker.update(scan.t, self.costmap.unmapped_points)
                self.costmap.set_predicted(self.tracker.predicted_points(self.costmap.resolution_m))
        goal = self.goal
        d_goal = math.hypot(goal.x_m - pose.x_m, goal.y_m - pose.y_m)

        # Final approach: once at the goal (latched, as move_base's latch_xy_goal_tolerance), turn to its
        # heading. "At the goal" is within ``arrive_m``, or within the tolerance when the local planner
        # cannot get closer, so the robot ends well inside the tolerance, not on its edge.
        route_driven = self.route is None or self.route.remaining_m <= p.xy_tolerance_m
        if route_driven and (d_goal <= p.arrive_m or self._xy_reached
                             or (d_goal <= p.xy_tolerance_m and self._creeping)):
            if not self._xy_reached:
                self.events.append(NavEvent(now, "position reached", f"{d_goal:.2f} m from the goal"))
            self._xy_reached = True
            err = float(wrap(goal.yaw_rad - pose.yaw_rad))
            if d_goal > p.xy_tolerance_m:  # pushed away while turning: approach again
                self._xy_reached = self._creeping = False
                self.events.append(NavEvent(now, "position lost", f"{d_goal:.2f} m from the goal"))
            elif abs(err) <= 0.5 * p.yaw_tolerance_rad:  # aim at half the tolerance: margin for estimate error
                return self._succeed(now, d_goal, err)
            else:
                return self._running(self.local.rotate(err, self._velocity, dt), "rotating to the goal heading",
                                     d_goal)

        if self._recovery is not None:
            twist, done = self._recovery.step(now, pose, self.costmap)
            if not done:
                if twist.is_zero:
                    twist = self.local.evade(pose, self._velocity, dt)
                return self._running(twist, f"recovery: {self._recovery.kind}", d_goal)
            self.events.append(NavEvent(now, "recovery done", self._recovery.kind))
            self._recovery = None
            self._no_path_since = None
            self._t_plan = -math.inf
            self._blocked_since = None
            self._t_progress = now

        # Global plan: periodic, at once when the path ahead became blocked; without one, wait and retry. Along
        # a route, every tick: the progress moves on and the local planner gets the stretch just ahead.
        if self.route is not None:
            due = True
        elif self._path is None:
            due = now - self._t_plan >= p.path_retry_s
        else:
            due = now - self._t_plan >= p.replan_period_s or self._path_blocked(pose)
        if due and not self._plan(now, pose) and self._no_path_since is None:
            self._no_path_since = now
        if self._path is None:
            if self._no_path_since is not None and now - self._no_path_since > p.path_wait_s:
                return self._begin_recovery(now, pose, "no path", d_goal)
            return self._running(self.local.evade(pose, self._velocity, dt), "no path: waiting", d_goal)
        self._no_path_since = None
        path = self._path.points
        left = self._left(pose, path)

        # Progress watchdog.
        if left < self._best_left - p.progress_m:
            self._best_left = left
            self._t_progress = now
        # A recovery worked when the robot got really closer (straight-line, not along a new plan: clearing the
        # costmap shortens the plan without moving anything); then the sequence may start over.
        if self._recovery_index and d_goal < self._recovery_d_goal - p.recovered_after_m:
            self._recovery_index = 0
            self._waiting_since = None
        if now - self._t_progress > p.stuck_timeout_s:
            return self._begin_recovery(now, pose, "stuck", d_goal)

        end = (float(path[-1, 0]), float(path[-1, 1]))  # the goal, or the nearest enterable cell to it
        plan = self.local.compute(pose, self._velocity, path, end, dt, zone=self._zone)
        self._trajectory = plan.trajectory
        if not plan.ok:
            if self._blocked_since is None:
                self._blocked_since = now
                self._t_plan = -math.inf  # replan at the next tick: the way may be open elsewhere
            if now - self._blocked_since > p.blocked_timeout_s:
                return self._begin_recovery(now, pose, "stuck", d_goal)
            return self._running(self.local.evade(pose, self._velocity, dt), "blocked: waiting", left)
        self._blocked_since = None
        self._creeping = abs(plan.twist.linear_mps) < 0.03
        return self._running(plan.twist, "following the path", left)

    # -- helpers -------------------------------------------------------------------------------------------
    def _plan(self, now: float, pose: Pose2D) -> bool:
        assert self.goal is not None
        before = self._path
        if self.route is not None:
            path = self._follow_route(now, pose)
        else:
            tolerance = max(self.params.xy_tolerance_m - 0.05, 0.0)
            path = self.planner.plan((pose.x_m, pose.y_m), (self.goal.x_m, self.goal.y_m), tolerance_m=tolerance)
        self._t_plan = now
        if path is None:
            if before is not None or not self._planned:
                self.events.append(NavEvent(now, "no path", f"from ({pose.x_m:.2f}, {pose.y_m:.2f})"))
            self._path = None
            self._planned = True
            return False
        self._path = path
        if before is None:
            # A way again after none: progress is judged from now (waiting for it was not being stuck), and after
            # a wait for the way to clear, the recoveries are all there again.
            self._t_progress = now
            if self._waiting_since is not None:
                self._waiting_since = None
                self._recovery_index = 0
        if self.route is not None:  # progress is judged along the route itself (the window moves every tick)
            if before is None:
                self.events.append(NavEvent(now, "replan" if self._planned else "plan",
                                            f"along the route, {self._left(pose, path.points):.2f} m"))
            self._planned = True
            return True
        # Progress is judged along the current plan: a detour round a new obstacle is progress too.
        left = self._distance_left(pose, path.points)
        self._best_left = left
        # Log a plan when there was none, or when the way changed (not every periodic replan).
        if before is None or abs(left - self._distance_left(pose, before.points)) > 0.5:
            self.events.append(NavEvent(now, "replan" if self._planned else "plan", f"{path.length_m:.2f} m"))
        self._planned = True
        return True

    def _follow_route(self, now: float, pose: Pose2D) -> GlobalPath | None:
        """The stretch of the route just ahead (`Route.window`), with an A* approach in front when the robot is
        off the route (re-planned at most every ``replan_period_s``), or None while the route just ahead is
        blocked (waited for like no path; never bypassed). The goal's own tolerance zone does not count as
        blocked: someone standing by the goal is handled as without a route."""
        assert self.route is not None and self.goal is not None
        route = self.route
        off_by = route.advance(pose.x_m, pose.y_m)
        rest = route.rest
        away = np.hypot(rest[:, 0] - self.goal.x_m, rest[:, 1] - self.goal.y_m) > self.params.xy_tolerance_m
        if away.any() and self._blocked_ahead(pose, rest[away]):
            return None
        window = route.window()
        expanded = 0
        if off_by <= JOIN_M:
            self._approach = None
            points = window
        else:
            target = (float(rest[0, 0]), float(rest[0, 1]))
            stale = (self._approach is None or now - self._t_approach >= self.params.replan_period_s
                     or math.dist(tuple(self._approach.points[-1]), target) > 1e-6)
            if stale:
                self._approach, self._t_approach = self.planner.plan((pose.x_m, pose.y_m), target), now
            if self._approach is None:
                return None
            points = np.concatenate([self._approach.points[:-1], window])
            expanded = self._approach.expanded
        return GlobalPath(points, np.zeros(0, dtype=np.intp), float(arc_lengths(points)[-1]), 0.0, expanded)

    def _left(self, pose: Pose2D, path: FloatArray) -> float:
        """Distance left to the goal: along the route (from its progress point, plus the way back onto it), or
        along the current plan."""
        if self.route is None:
            return self._distance_left(pose, path)
        here = self.route.rest[0]
        return self.route.remaining_m + math.hypot(here[0] - pose.x_m, here[1] - pose.y_m)

    def _path_blocked(self, pose: Pose2D) -> bool:
        """Whether a stretch of the current path just ahead now lies in the inscribed zone."""
        if self._path is None:
            return True
        return self._blocked_ahead(pose, self._path.points)

    def _blocked_ahead(self, pose: Pose2D, pts: FloatArray) -> bool:
        """Whether the stretch of ``pts`` within the look-ahead of the robot lies in the inscribed zone."""
        i, s = path_progress(pts, pose.x_m, pose.y_m)
        j = int(np.searchsorted(s, s[i] + self.params.blocked_lookahead_m))
        ahead = pts[i:j + 1]
        # Skip the stretch under and right around the robot: it may start in the inscribed zone (pushed
        # against something) and the planner lets it out through there.
        ahead = ahead[np.hypot(ahead[:, 0] - pose.x_m, ahead[:, 1] - pose.y_m) > self.params.planner.escape_radius_m]
        if len(ahead) == 0:
            return False
        return bool((self.costmap.cost_at(ahead[:, 0], ahead[:, 1]) >= INSCRIBED).any())

    @staticmethod
    def _distance_left(pose: Pose2D, path: FloatArray) -> float:
        i, s = path_progress(path, pose.x_m, pose.y_m)
        return float(s[-1] - s[i] + math.hypot(path[i, 0] - pose.x_m, path[i, 1] - pose.y_m))

    def _map_has_path(self, pose: Pose2D) -> bool:
        """Whether start and goal lie in one connected part of the map's free space (ignoring the live layers)."""
        assert self.goal is not None
        xs, ys = np.array([pose.x_m, self.goal.x_m]), np.array([pose.y_m, self.goal.y_m])
        rows, cols, inside = self.costmap.cells(xs, ys)
        if not inside.all():
            return False
        here, there = (int(v) for v in self._static_parts[rows, cols])
        return here != 0 and here == there

    def _begin_recovery(self, now: float, pose: Pose2D, why: FailReason, d_goal: float) -> NavStatus:
        seq = self.params.recovery.sequence
        self._last_failure = why
        if self._recovery_index >= len(seq) and why == "no path" and self._map_has_path(pose):
            if self._waiting_since is None:
                self._waiting_since = now
                self.events.append(NavEvent(now, "waiting", "the way is blocked by obstacles not in the map"))
            if now - self._waiting_since <= self.params.obstacle_wait_s:
                self._no_path_since = now  # plan again every path_retry_s, look at this again after path_wait_s
                return self._running(ZERO_TWIST, "no path: waiting for the way to clear", d_goal)
        if self._recovery_index >= len(seq):
            detail = {"no path": "no path to the goal", "stuck": "the robot is stuck"}.get(why, why)
            return self._fail(now, why, f"{detail} after recoveries ({', '.join(seq)})")
        kind = seq[self._recovery_index]
        self._recovery_index += 1
        self._recovery_d_goal = min(self._recovery_d_goal, d_goal)
        self._recovery = RecoveryBehaviour(kind, self.params.recovery, now, pose)
        self._blocked_since = None
        self.events.append(NavEvent(now, "recovery", f"{kind} ({why})"))
        return self._running(ZERO_TWIST, f"recovery: {kind}", d_goal)

    def _running(self, twist: Twist, phase: str, left: float = math.nan) -> NavStatus:
        self._velocity = twist
        speed = max(0.6 * self.params.local.max_linear_mps, 0.05)
        path = self._path.points if self._path is not None else _EMPTY
        return NavStatus("RUNNING", twist, phase, left, left / speed if math.isfinite(left) else math.nan, path,
                         self._trajectory, None, "", self._recovery.kind if self._recovery else None)

    def _fail(self, now: float, why: FailReason, message: str) -> NavStatus:
        self.state = "FAILED"
        self._velocity = ZERO_TWIST
        self.events.append(NavEvent(now, "failed", f"{why}: {message}"))
        path = self._path.points if self._path is not None else _EMPTY
        self._final = NavStatus("FAILED", ZERO_TWIST, "failed", math.nan, math.nan, path, _EMPTY, why,
                                f"{why}: {message}")
        return self._final

    def _succeed(self, now: float, d_goal: float, yaw_err: float) -> NavStatus:
        self.state = "SUCCEEDED"
        self._velocity = ZERO_TWIST
        self.events.append(NavEvent(now, "succeeded", f"{d_goal:.2f} m, {yaw_err:.2f} rad from the goal"))
        path = self._path.points if self._path is not None else _EMPTY
        self._final = NavStatus("SUCCEEDED", ZERO_TWIST, "reached", d_goal, 0.0, path, _EMPTY, None,
                                f"reached within {d_goal:.2f} m and {abs(yaw_err):.2f} rad")
        return self._final
