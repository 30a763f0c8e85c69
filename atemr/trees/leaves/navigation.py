"""Navigation leaves: go to a pose or along a route through the `NavigationPort` (planners, costmap,
recoveries live behind it), and relocalize through the robot port."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import py_trees

from atemr.clock import due
from atemr.domain.places import check_name
from atemr.errors import AtemrError, ConfigError, NavigationError
from atemr.msgs import ZERO_TWIST, Pose2D, Twist
from atemr.trees.behaviours import Leaf, behaviours
from atemr.trees.leaves.motion import wrap_angle
from atemr.trees.params import PoseParams
from atemr.trees.ports import NavigationPort

Status = py_trees.common.Status

#: Navigation's goal step; a goal can be executed only once a behaviour of this name is registered.
GO_TO_POSE = "GoToPose"
#: Navigation's route step (`FollowPath`).
FOLLOW_PATH = "FollowPath"
#: Navigation's step to a named place of the active map (`GoToPlace`).
GO_TO_PLACE = "GoToPlace"
#: The steps that drive the base through navigation (a mission with one needs navigation on the robot).
DRIVES = (GO_TO_POSE, FOLLOW_PATH, GO_TO_PLACE)


class NavigationGoal(Leaf):
    """What `GoToPose` and `FollowPath` share: hand navigation a goal in ``initialise`` (``start``; a refusal
    is this leaf's FAILURE with the navigator's reason), then each ``update`` ticks navigation and commands
    its twist on the mux's navigation input; SUCCESS when the goal is reached within the navigator's
    tolerances, FAILURE with the reason (no path, stuck, localization lost, timeout). Interrupted (cancel,
    timeout decorator, a state change) it cancels the goal; it always leaves a zero twist behind.
    """

    def start(self, navigation: NavigationPort) -> None:
        """Hand navigation the goal (raises its refusal)."""
        raise NotImplementedError

    def initialise(self) -> None:
        self._started = False
        self._refusal = ""
        navigation = self.ctx.navigation
        if navigation is None:
            self._refusal = "navigation is not available on this robot"
            return
        try:
            self.start(navigation)
        except AtemrError as exc:
            self._refusal = f"goal refused: {exc}"
            return
        self._started = True

    def update(self) -> py_trees.common.Status:
        if not self._started or self.ctx.navigation is None:
            return self.fail(self._refusal or "navigation did not start")
        progress = self.ctx.navigation.update(self.ctx.now)
        if progress.state == "RUNNING":
            self.ctx.port.command_velocity("navigation", progress.twist, self.ctx.now)
            left = "" if math.isnan(progress.distance_left_m) else f"{progress.distance_left_m:.2f} m left"
            eta = "" if math.isnan(progress.eta_s) else f", ETA {progress.eta_s:.0f} s"
            self.feedback_message = left + eta
            return Status.RUNNING
        self._started = False
        self.ctx.port.command_velocity("navigation", ZERO_TWIST, self.ctx.now)
        if progress.state == "SUCCEEDED":
            self.feedback_message = "reached"
            return Status.SUCCESS
        return self.fail(f"navigation {progress.state.lower()}: {progress.reason or 'no reason given'}")

    def terminate(self, new_status: py_trees.common.Status) -> None:
        if self._context is None:
            return
        navigation = self.ctx.navigation
        if new_status == Status.INVALID and getattr(self, "_started", False) and navigation is not None:
            navigation.cancel(self.ctx.now)
            self._started = False
        self.ctx.port.command_velocity("navigation", ZERO_TWIST, self.ctx.now)


@behaviours.register(GO_TO_POSE)
class GoToPose(NavigationGoal):
    """Drive to ``(x_m, y_m, yaw_rad)`` in the map frame by navigation's own plan (see `NavigationGoal`)."""

    Params = PoseParams
    summary = "drive to a pose in the map with navigation"

    def start(self, navigation: NavigationPort) -> None:
        navigation.start(self.params.pose(), self.ctx.now)


@dataclass(frozen=True)
class PlaceParams:
    """A named place of the active map (``kitchen``, ``home``): the parameters of ``GoToPlace``."""

    place: str = field(default="", metadata={"required": True})

    def validate(self) -> None:
        try:
            check_name(self.place)
        except ConfigError as exc:
            raise ValueError(exc.reason) from None


@behaviours.register(GO_TO_PLACE)
class GoToPlace(NavigationGoal):
    """Drive to a named place of the active map. The name is looked up when the step starts, not when the
    mission is written, so a place moved on the dashboard is where the robot goes next; a place that is no
    longer there fails the step with the closest names (see `NavigationGoal`)."""

    Params = PlaceParams
    summary = "drive to a named place of the active map with navigation"

    def start(self, navigation: NavigationPort) -> None:
        try:
            place = navigation.places().find(self.params.place)
        except ConfigError as exc:
            raise NavigationError(exc.reason) from None
        navigation.start(place.pose, self.ctx.now)


@dataclass(frozen=True)
class FollowPathParams:
    """A route in the map frame: ``points`` ``[[x_m, y_m], ...]`` driven through in order, the last one the goal;
    ``yaw_rad`` the heading to end with (default: the direction of the last stretch)."""

    points: tuple[tuple[float, ...], ...] = field(default=(), metadata={"required": True})
    yaw_rad: float | None = field(default=None, metadata={"min": -2 * math.pi, "max": 2 * math.pi})

    def validate(self) -> None:
        if not self.points:
            raise ValueError("'points' needs at least one point [x_m, y_m]")
        for i, point in enumerate(self.points):
            if len(point) != 2:
                raise ValueError(f"points[{i}] must be [x_m, y_m], got {list(point)!r}")
            if not all(abs(v) <= 1e4 for v in point):
                raise ValueError(f"points[{i}] must lie within 10 km of the map origin, got {list(point)!r}")

    def pose(self) -> Pose2D:
        """The goal: the last point, facing ``yaw_rad``, else along the last stretch (from the last point
        before it that differs); a route of one point (or of one place) without ``yaw_rad`` ends facing 0 rad."""
        x, y = self.points[-1]
        if self.yaw_rad is not None:
            return Pose2D(x, y, self.yaw_rad)
        before = [p for p in self.points[:-1] if (p[0], p[1]) != (x, y)]
        yaw = math.atan2(y - before[-1][1], x - before[-1][0]) if before else 0.0
        return Pose2D(x, y, yaw)


@behaviours.register(FOLLOW_PATH)
class FollowPath(NavigationGoal):
    """Drive along a route: through ``points`` in order to the last one (Nav2's FollowPath; navigation
    follows the route, not its own shortest way, and fails rather than take another way); see
    `NavigationGoal`."""

    Params = FollowPathParams
    summary = "drive along a route of points, in order, to the last one"

    def start(self, navigation: NavigationPort) -> None:
        route = [(float(x), float(y)) for x, y in self.params.points[:-1]]
        navigation.start(self.params.pose(), self.ctx.now, route=route)


class TurnInPlace:
    """At most one revolution in place, counted on the odometry's heading (which needs no map: it works while the
    robot does not know where it is): the turn `Relocalize` makes to see more while the search is ambiguous."""

    def __init__(self) -> None:
        self.turned_rad = 0.0
        self._last_yaw: float | None = None

    def advance(self, pose: Pose2D | None) -> bool:
        """Count the heading change since the last call; whether to go on turning (False once a revolution is
        done, or without a heading to count it by)."""
        if pose is None:
            return False
        if self._last_yaw is not None:
            self.turned_rad += abs(wrap_angle(pose.yaw_rad - self._last_yaw))
        self._last_yaw = pose.yaw_rad
        return self.turned_rad < 2 * math.pi


@dataclass(frozen=True)
class RelocalizeParams:
    timeout_s: float = field(default=30.0, metadata={"min": 0.1, "max": 600.0})
    #: Turn in place while the search is ambiguous (at most one revolution), to see more before it decides.
    turn: bool = True
    turn_speed_radps: float = field(default=0.4, metadata={"min": 0.05, "max": 1.6})


@behaviours.register("Relocalize")
class Relocalize(Leaf):
    """Start global relocalization and wait until the robot is localized again (FAILURE after ``timeout_s``).

    For a robot that knows it is lost (the covariance monitor) or was moved by hand. While the search answers
    *ambiguous* (look-alike places: the bays of a warehouse, two identical rooms) the robot turns in place, at
    most one revolution, as issue 21 allows: the localizer pools a scan every 45 degrees, and each one seen from
    a turned lidar (its beams at other angles, the sensor 10 cm off the axis, fresh noise) adds the evidence one
    scan could not give. On the warehouse map a turn decides 8 of the 12 ambiguous places of the benchmark's
    seeded poses, most after the first 45 degrees (`benchmarks/global_localization.py --turn`); the rest are
    places whose scans differ in no beam. ``turn: false`` waits without moving. Commands on the pipeline's
    ``agent`` input, under the safety stop like every motion.
    """

    Params = RelocalizeParams
    summary = "relocalize globally on the active map (turning in place while ambiguous), wait until localized"

    def initialise(self) -> None:
        self._deadline = self.ctx.now + self.params.timeout_s
        self._refusal = ""
        self._turn = TurnInPlace()
        self._turning = False
        try:
            self.ctx.port.relocalize(self.ctx.now)
        except AtemrError as exc:
            self._refusal = f"cannot relocalize: {exc}"

    def update(self) -> py_trees.common.Status:
        if self._refusal:
            return self.fail(self._refusal)
        status = self.ctx.port.localization_status()
        if status is not None and status.localized:
            self._stop_turning()
            self.feedback_message = "localized"
            return Status.SUCCESS
        if due(self.ctx.now, self._deadline):
            self._stop_turning()
            return self.fail(f"not localized after {self.params.timeout_s:g} s")
        if (status is not None and status.state == "ambiguous" and self.params.turn
                and self._turn.advance(self.ctx.port.odom_pose())):
            self.ctx.port.command_velocity("agent", Twist(0.0, self.params.turn_speed_radps), self.ctx.now)
            self._turning = True
            self.feedback_message = f"ambiguous: turning to see more ({math.degrees(self._turn.turned_rad):.0f} deg)"
            return Status.RUNNING
        self._stop_turning()
        self.feedback_message = "relocalizing"
        return Status.RUNNING

    def _stop_turning(self) -> None:
        if self._turning:
            self.ctx.port.command_velocity("agent", ZERO_TWIST, self.ctx.now)
            self._turning = False

    def terminate(self, new_status: py_trees.common.Status) -> None:
        if self._context is not None and getattr(self, "_turning", False):
            self._stop_turning()
