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

What it is doing is named by its `Phase` (one method each, which ``update`` dispatches to), and all it keeps
about one goal is one `_Run`, replaced whole by the next ``start``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.domain.maps import OccupancyMap
from atemr.errors import NavigationError
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
    #: A robot that creeps (the local planner cannot get closer: a goal by a wall) is at the goal this far inside
    #: the tolerance (never farther out than ``arrive_m``): the pose it judges by may be that far off.
    creep_margin_m: float = 0.05
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
        for name in ("xy_tolerance_m", "yaw_tolerance_rad", "arrive_m", "creep_margin_m", "replan_period_s",
                     "blocked_lookahead_m", "blocked_timeout_s", "path_wait_s", "path_retry_s", "stuck_timeout_s",
                     "progress_m", "recovered_after_m", "localization_timeout_s", "obstacle_wait_s", "timeout_s"):
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


class Phase(Enum):
    """What the navigator is doing for its goal; `Navigator.update` runs the method of the phase.

    FOLLOWING, NO_PATH and BLOCKED are the driving phases: each tick plans when a plan is due and then
    finds which of them applies (is there a path; can the local planner follow it). The other three run
    instead of driving, and LOST and TURNING go back to the phase they interrupted.
    """

    #: A path, and a safe local move along it.
    FOLLOWING = "following"
    #: The last plan found no path: wait, stepping out of the way of whoever comes close, and plan again every
    #: ``path_retry_s``; after ``path_wait_s``, the next recovery.
    NO_PATH = "no path"
    #: A path, but the local planner finds no safe move along it: wait, stepping aside; after
    #: ``blocked_timeout_s``, the next recovery.
    BLOCKED = "blocked"
    #: One recovery behaviour runs (`RecoveryBehaviour`); then driving again.
    RECOVERING = "recovering"
    #: At the goal (latched, as move_base's latch_xy_goal_tolerance): turning on the spot to its heading.
    TURNING = "turning"
    #: Not localized: stand still; fail after ``localization_timeout_s``.
    LOST = "lost"


@dataclass(frozen=True)
class _Tick:
    """What every phase method gets: the time, the pose, the period since the last tick, the distance to the goal."""

    now: float
    pose: Pose2D
    dt: float
    d_goal: float


@dataclass
class _Run:
    """Everything a navigator keeps while it pursues one goal: `start` replaces it with a new one, so nothing of
    the last goal (a phase, a timer, a half-used recovery sequence) carries over to the next."""

    t_start: float = 0.0
    # -- the phase, and the phase LOST and TURNING go back to (kept apart: the robot may be lost while turning)
    phase: Phase = Phase.FOLLOWING
    lost_from: Phase = Phase.FOLLOWING
    turn_from: Phase = Phase.FOLLOWING
    #: When LOST began (its timeout counts from it).
    lost_since: float = math.nan
    #: When NO_PATH began; the wait for the way to clear sets it again (its wait counts from it).
    no_path_since: float = math.nan
    #: The first tick without a safe local move (BLOCKED's timeout counts from it). A no-path spell between two
    #: blocked ones does not reset it (the robot had no safe move then either); a safe move or a recovery does.
    blocked_since: float | None = None
    # -- the tick before: for dt, the velocity the local planner starts from, the last scan folded in
    t_last: float = math.nan
    velocity: Twist = ZERO_TWIST
    last_scan_t: float = math.nan
    #: What the motion pipeline's stop zone will judge the next commands by (nearest return ahead, behind).
    zone: tuple[float, float] | None = None
    # -- the global plan
    path: GlobalPath | None = None
    t_plan: float = -math.inf
    #: A plan was made or tried for this goal (the events then say "replan", not "plan").
    planned: bool = False
    #: Along a route, off it: the A* way back onto it, and when it was planned.
    approach: GlobalPath | None = None
    t_approach: float = -math.inf
    #: Why the route does not fit a map selected while driving it (the next update fails the goal).
    route_refused: str | None = None
    # -- the progress watchdog: the least distance left (along the plan or the route) and when it last shrank
    best_left: float = math.inf
    t_progress: float = 0.0
    #: The last local command was a creep (inside the tolerance, that is arriving).
    creeping: bool = False
    trajectory: FloatArray = field(default_factory=lambda: _EMPTY)
    # -- recoveries: the next in the sequence, the one running, the straight-line distance to beat to count as
    # recovered, and when the wait for the way to clear began (the sequence used up, the map has a path)
    recovery_index: int = 0
    recovery: RecoveryBehaviour | None = None
    recovery_d_goal: float = math.inf
    clear_wait_since: float | None = None
    #: The answer once the goal succeeded, failed or was canceled.
    final: NavStatus | None = None


class Navigator:
    """Drives the base to one goal at a time on one map; see the module doc and `Phase`."""

    def __init__(self, occupancy: OccupancyMap, params: NavParams | None = None, *,
                 prepared: NavMap | None = None) -> None:
        self.params = params or NavParams()
        self.events: list[NavEvent] = []
        self.goal: Pose2D | None = None
        self.route: Route | None = None
        self.state: NavState = "IDLE"
        self._run = _Run()
        self.set_map(occupancy, prepared)

    @property
    def phase(self) -> Phase:
        """The phase of the current (or last) goal."""
        return self._run.phase

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
        self._run.path = None
        self._static_parts = nav_map.static_parts
        if self.route is not None and self.state == "RUNNING":
            why = self.route.refusal(self.costmap)
            if why is not None:
                self._run.route_refused = f"the route does not fit the new map: {why}"

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
        self._run = _Run(t_start=now, t_progress=now)
        self.goal = goal
        self.route = planned_route
        self.state = "RUNNING"
        self.events.append(NavEvent(now, "goal", f"({goal.x_m:.2f}, {goal.y_m:.2f}, {goal.yaw_rad:.2f})"
                                    + (f" along a {planned_route.length_m:.2f} m route" if planned_route else "")))
        return verdict

    def cancel(self, now: float | None = None) -> NavStatus:
        """Stop pursuing the goal; the next update returns CANCELED with a zero twist."""
        run = self._run
        if self.state == "RUNNING":
            self.state = "CANCELED"
            run.final = NavStatus("CANCELED", phase="canceled", message="goal canceled")
            self.events.append(NavEvent(now if now is not None else run.t_last, "canceled"))
        return run.final or NavStatus(self.state)

    # -- the tick ------------------------------------------------------------------------------------------
    def update(self, now: float, pose: Pose2D, scan: LaserScan | None = None, localized: bool = True,
               velocity: Twist | None = None) -> NavStatus:
        """One navigation tick; ``velocity`` is the measured twist if known (else the last command is used).

        The checks that hold in every phase come first (the overall timeout, a route the map ruled out, the
        localization); then the scan goes into the costmap, arriving at the goal starts TURNING whatever the
        robot was doing, and the method of the phase answers."""
        run = self._run
        if self.state != "RUNNING" or self.goal is None:
            return run.final or NavStatus(self.state)
        p = self.params
        dt = p.local.control_period_s if math.isnan(run.t_last) else min(max(now - run.t_last, 1e-3), 1.0)
        run.t_last = now
        if velocity is not None:
            run.velocity = velocity
        if now - run.t_start > p.timeout_s:
            return self._fail(now, "timeout", f"goal not reached within {p.timeout_s:.0f} s")
        if run.route_refused is not None:
            return self._fail(now, "no path", run.route_refused)
        if not (localized and all(math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad))):
            return self._lost(now)
        if run.phase is Phase.LOST:
            self._relocalized(now)
        self._fold_scan(scan, pose)
        tick = _Tick(now, pose, dt, math.hypot(self.goal.x_m - pose.x_m, self.goal.y_m - pose.y_m))
        if run.phase is not Phase.TURNING and self._arrived(tick.d_goal):
            self.events.append(NavEvent(now, "position reached", f"{tick.d_goal:.2f} m from the goal"))
            run.turn_from, run.phase = run.phase, Phase.TURNING
        return self._dispatch(tick)

    def _dispatch(self, tick: _Tick) -> NavStatus:
        """The answer of the current phase (LOST is settled before: it needs no pose)."""
        match self._run.phase:
            case Phase.TURNING:
                return self._turn(tick)
            case Phase.RECOVERING:
                return self._recover(tick)
            case _:
                return self._drive(tick)

    def _fold_scan(self, scan: LaserScan | None, pose: Pose2D) -> None:
        """A new scan into the costmap, the stop zone, and (predicting movers) the tracker and predicted layer."""
        run = self._run
        if scan is None or scan.t == run.last_scan_t:
            return
        self.costmap.update_from_scan(scan, pose)
        run.last_scan_t = scan.t
        front, rear, _ = hex_pattern(scan, HEX90).nearest_by_direction()
        run.zone = (front, rear)
        if self.params.predict_movers:
            self.tracker.update(scan.t, self.costmap.unmapped_points)
            self.costmap.set_predicted(self.tracker.predicted_points(self.costmap.resolution_m))

    def _arrived(self, d_goal: float) -> bool:
        """Whether the robot is at the goal: within ``arrive_m``, or, when the local planner cannot get closer (it
        creeps), within the tolerance less ``creep_margin_m``, so that the robot ends inside the tolerance even
        if its pose is that far off, not on the edge by its own account. Along a route, only once the route is
        driven (it may pass by the goal before)."""
        p, run = self.params, self._run
        route_driven = self.route is None or self.route.remaining_m <= p.xy_tolerance_m
        creep_arrive_m = max(p.arrive_m, p.xy_tolerance_m - p.creep_margin_m)
        return route_driven and (d_goal <= p.arrive_m or (d_goal <= creep_arrive_m and run.creeping))

    # -- the phases ----------------------------------------------------------------------------------------
    def _lost(self, now: float) -> NavStatus:
        """LOST: stand still until localized again (`_relocalized`), and fail after ``localization_timeout_s``."""
        run, p = self._run, self.params
        if run.phase is not Phase.LOST:
            run.lost_from, run.phase, run.lost_since = run.phase, Phase.LOST, now
            self.events.append(NavEvent(now, "waiting", "localization lost: stopped"))
        if now - run.lost_since > p.localization_timeout_s:
            return self._fail(now, "localization lost", f"not localized for {p.localization_timeout_s:.0f} s")
        return self._running(ZERO_TWIST, "waiting for localization")

    def _relocalized(self, now: float) -> None:
        """Back to the phase LOST interrupted; standing still was not being stuck, and the pose may have jumped,
        so progress counts from now and the next driving tick plans."""
        run = self._run
        self.events.append(NavEvent(now, "localized", "going on"))
        run.phase = run.lost_from
        run.t_progress = now
        run.t_plan = -math.inf

    def _turn(self, tick: _Tick) -> NavStatus:
        """TURNING: turn on the spot to the goal's heading; pushed out of the tolerance, back to the phase it
        interrupted (approach again)."""
        run, p = self._run, self.params
        assert self.goal is not None
        err = float(wrap(self.goal.yaw_rad - tick.pose.yaw_rad))
        if tick.d_goal > p.xy_tolerance_m:
            run.phase, run.creeping = run.turn_from, False
            self.events.append(NavEvent(tick.now, "position lost", f"{tick.d_goal:.2f} m from the goal"))
            return self._dispatch(tick)
        if abs(err) <= 0.5 * p.yaw_tolerance_rad:  # aim at half the tolerance: margin for estimate error
            return self._succeed(tick.now, tick.d_goal, err)
        return self._running(self.local.rotate(err, run.velocity, tick.dt), "rotating to the goal heading",
                             tick.d_goal)

    def _recover(self, tick: _Tick) -> NavStatus:
        """RECOVERING: step the recovery (evading when it stands still); once done, drive again this tick, with
        a fresh plan, and progress counted from now."""
        run = self._run
        assert run.recovery is not None
        twist, done = run.recovery.step(tick.now, tick.pose, self.costmap)
        if not done:
            if twist.is_zero:
                twist = self.local.evade(tick.pose, run.velocity, tick.dt)
            return self._running(twist, f"recovery: {run.recovery.kind}", tick.d_goal)
        self.events.append(NavEvent(tick.now, "recovery done", run.recovery.kind))
        run.recovery = None
        run.phase = Phase.FOLLOWING
        run.t_plan = -math.inf
        run.blocked_since = None
        run.t_progress = tick.now
        return self._drive(tick)

    def _drive(self, tick: _Tick) -> NavStatus:
        """FOLLOWING, NO_PATH or BLOCKED: plan when due, then whichever of them applies; the progress watchdog
        starts a recovery when the distance left has not shrunk for ``stuck_timeout_s``."""
        run, p = self._run, self.params
        now, pose, d_goal = tick.now, tick.pose, tick.d_goal
        if self._plan_due(now, pose) and not self._plan(now, pose) and run.phase is not Phase.NO_PATH:
            run.phase, run.no_path_since = Phase.NO_PATH, now
        if run.path is None:
            return self._no_path(tick)
        if run.phase is Phase.NO_PATH:  # a path again; the local planner tells FOLLOWING from BLOCKED
            run.phase = Phase.FOLLOWING
        path = run.path.points
        left = self._left(pose, path)
        if left < run.best_left - p.progress_m:
            run.best_left = left
            run.t_progress = now
        # A recovery worked when the robot got really closer (straight-line, not along a new plan: clearing the
        # costmap shortens the plan without moving anything); then the sequence may start over.
        if run.recovery_index and d_goal < run.recovery_d_goal - p.recovered_after_m:
            run.recovery_index = 0
            run.clear_wait_since = None
        if now - run.t_progress > p.stuck_timeout_s:
            return self._begin_recovery(now, pose, "stuck", d_goal)
        end = (float(path[-1, 0]), float(path[-1, 1]))  # the goal, or the nearest enterable cell to it
        plan = self.local.compute(pose, run.velocity, path, end, tick.dt, zone=run.zone)
        run.trajectory = plan.trajectory
        if not plan.ok:
            return self._blocked(tick, left)
        run.phase = Phase.FOLLOWING
        run.blocked_since = None
        run.creeping = abs(plan.twist.linear_mps) < 0.03
        return self._running(plan.twist, "following the path", left)

    def _plan_due(self, now: float, pose: Pose2D) -> bool:
        """Whether to plan this tick: periodically, and at once when the path ahead became blocked; without a
        path, every ``path_retry_s``. Along a route, every tick: the progress moves on and the local planner
        gets the stretch just ahead."""
        run, p = self._run, self.params
        if self.route is not None:
            return True
        if run.path is None:
            return now - run.t_plan >= p.path_retry_s
        return now - run.t_plan >= p.replan_period_s or self._path_blocked(pose)

    def _no_path(self, tick: _Tick) -> NavStatus:
        """No global path (NO_PATH, or a new map dropped the path and the next plan is not due): wait, evading;
        in NO_PATH for more than ``path_wait_s``, the next recovery."""
        run = self._run
        if run.phase is Phase.NO_PATH and tick.now - run.no_path_since > self.params.path_wait_s:
            return self._begin_recovery(tick.now, tick.pose, "no path", tick.d_goal)
        return self._running(self.local.evade(tick.pose, run.velocity, tick.dt), "no path: waiting", tick.d_goal)

    def _blocked(self, tick: _Tick, left: float) -> NavStatus:
        """BLOCKED: no safe local move. Wait, evading; plan again at once the first time (the way may be open
        elsewhere); after ``blocked_timeout_s``, the next recovery."""
        run = self._run
        run.phase = Phase.BLOCKED
        if run.blocked_since is None:
            run.blocked_since = tick.now
            run.t_plan = -math.inf
        if tick.now - run.blocked_since > self.params.blocked_timeout_s:
            return self._begin_recovery(tick.now, tick.pose, "stuck", tick.d_goal)
        return self._running(self.local.evade(tick.pose, run.velocity, tick.dt), "blocked: waiting", left)

    def _begin_recovery(self, now: float, pose: Pose2D, why: FailReason, d_goal: float) -> NavStatus:
        """RECOVERING with the next recovery of the sequence. The sequence used up: fail, unless there is no path
        only past what the scan sees (the map has one): then NO_PATH goes on, up to ``obstacle_wait_s``."""
        run, seq = self._run, self.params.recovery.sequence
        if run.recovery_index >= len(seq) and why == "no path" and self._map_has_path(pose):
            if run.clear_wait_since is None:
                run.clear_wait_since = now
                self.events.append(NavEvent(now, "waiting", "the way is blocked by obstacles not in the map"))
            if now - run.clear_wait_since <= self.params.obstacle_wait_s:
                run.no_path_since = now  # plan again every path_retry_s, look at this again after path_wait_s
                return self._running(ZERO_TWIST, "no path: waiting for the way to clear", d_goal)
        if run.recovery_index >= len(seq):
            detail = {"no path": "no path to the goal", "stuck": "the robot is stuck"}.get(why, why)
            return self._fail(now, why, f"{detail} after recoveries ({', '.join(seq)})")
        kind = seq[run.recovery_index]
        run.recovery_index += 1
        run.recovery_d_goal = min(run.recovery_d_goal, d_goal)
        run.recovery = RecoveryBehaviour(kind, self.params.recovery, now, pose)
        run.phase = Phase.RECOVERING
        run.blocked_since = None
        self.events.append(NavEvent(now, "recovery", f"{kind} ({why})"))
        return self._running(ZERO_TWIST, f"recovery: {kind}", d_goal)

    # -- helpers -------------------------------------------------------------------------------------------
    def _plan(self, now: float, pose: Pose2D) -> bool:
        run = self._run
        assert self.goal is not None
        before = run.path
        if self.route is not None:
            path = self._follow_route(now, pose)
        else:
            tolerance = max(self.params.xy_tolerance_m - 0.05, 0.0)
            path = self.planner.plan((pose.x_m, pose.y_m), (self.goal.x_m, self.goal.y_m), tolerance_m=tolerance)
        run.t_plan = now
        if path is None:
            if before is not None or not run.planned:
                self.events.append(NavEvent(now, "no path", f"from ({pose.x_m:.2f}, {pose.y_m:.2f})"))
            run.path = None
            run.planned = True
            return False
        run.path = path
        if before is None:
            # A way again after none: progress is judged from now (waiting for it was not being stuck), and after
            # a wait for the way to clear, the recoveries are all there again.
            run.t_progress = now
            if run.clear_wait_since is not None:
                run.clear_wait_since = None
                run.recovery_index = 0
        if self.route is not None:  # progress is judged along the route itself (the window moves every tick)
            if before is None:
                self.events.append(NavEvent(now, "replan" if run.planned else "plan",
                                            f"along the route, {self._left(pose, path.points):.2f} m"))
            run.planned = True
            return True
        # Progress is judged along the current plan: a detour round a new obstacle is progress too.
        left = self._distance_left(pose, path.points)
        run.best_left = left
        # Log a plan when there was none, or when the way changed (not every periodic replan).
        if before is None or abs(left - self._distance_left(pose, before.points)) > 0.5:
            self.events.append(NavEvent(now, "replan" if run.planned else "plan", f"{path.length_m:.2f} m"))
        run.planned = True
        return True

    def _follow_route(self, now: float, pose: Pose2D) -> GlobalPath | None:
        """The stretch of the route just ahead (`Route.window`), with an A* approach in front when the robot is
        off the route (re-planned at most every ``replan_period_s``), or None while the route just ahead is
        blocked (waited for like no path; never bypassed). The goal's own tolerance zone does not count as
        blocked: someone standing by the goal is handled as without a route."""
        assert self.route is not None and self.goal is not None
        run, route = self._run, self.route
        off_by = route.advance(pose.x_m, pose.y_m)
        rest = route.rest
        away = np.hypot(rest[:, 0] - self.goal.x_m, rest[:, 1] - self.goal.y_m) > self.params.xy_tolerance_m
        if away.any() and self._blocked_ahead(pose, rest[away]):
            return None
        window = route.window()
        expanded = 0
        if off_by <= JOIN_M:
            run.approach = None
            points = window
        else:
            target = (float(rest[0, 0]), float(rest[0, 1]))
            stale = (run.approach is None or now - run.t_approach >= self.params.replan_period_s
                     or math.dist(tuple(run.approach.points[-1]), target) > 1e-6)
            if stale:
                run.approach, run.t_approach = self.planner.plan((pose.x_m, pose.y_m), target), now
            if run.approach is None:
                return None
            points = np.concatenate([run.approach.points[:-1], window])
            expanded = run.approach.expanded
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
        if self._run.path is None:
            return True
        return self._blocked_ahead(pose, self._run.path.points)

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

    def _running(self, twist: Twist, phase: str, left: float = math.nan) -> NavStatus:
        run = self._run
        run.velocity = twist
        speed = max(0.6 * self.params.local.max_linear_mps, 0.05)
        path = run.path.points if run.path is not None else _EMPTY
        return NavStatus("RUNNING", twist, phase, left, left / speed if math.isfinite(left) else math.nan, path,
                         run.trajectory, None, "", run.recovery.kind if run.recovery else None)

    def _fail(self, now: float, why: FailReason, message: str) -> NavStatus:
        run = self._run
        self.state = "FAILED"
        run.velocity = ZERO_TWIST
        self.events.append(NavEvent(now, "failed", f"{why}: {message}"))
        path = run.path.points if run.path is not None else _EMPTY
        run.final = NavStatus("FAILED", ZERO_TWIST, "failed", math.nan, math.nan, path, _EMPTY, why,
                              f"{why}: {message}")
        return run.final

    def _succeed(self, now: float, d_goal: float, yaw_err: float) -> NavStatus:
        run = self._run
        self.state = "SUCCEEDED"
        run.velocity = ZERO_TWIST
        self.events.append(NavEvent(now, "succeeded", f"{d_goal:.2f} m, {yaw_err:.2f} rad from the goal"))
        path = run.path.points if run.path is not None else _EMPTY
        run.final = NavStatus("SUCCEEDED", ZERO_TWIST, "reached", d_goal, 0.0, path, _EMPTY, None,
                              f"reached within {d_goal:.2f} m and {abs(yaw_err):.2f} rad")
        return run.final
