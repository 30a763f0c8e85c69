"""Recording implementations of the agent's ports, for tests and for running the agent without a robot.

They are not stubs of the robot: they hold exactly the state a test sets (health, pose, joystick, what the
map would answer) and record every call the agent makes, so a test asserts on what the agent did.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from atemr.domain.places import Places
from atemr.domain.status import BatteryStatus, ComponentHealth, LocalizationState, LocalizationStatus, PowerState
from atemr.errors import HardwareError, NavigationError
from atemr.io.can import PrimaryStatus
from atemr.msgs import Pose2D, Twist
from atemr.trees.ports import HARDWARE_COMPONENTS, Mode, NavProgress, NavState, VelocitySource


def all_healthy() -> dict[str, ComponentHealth]:
    """Every hardware component of 0x153 reported healthy, plus connectivity and the CAN bus (``can_bus``, which
    the default agent's Monitor watches)."""
    return {**{name: ComponentHealth(True) for name in HARDWARE_COMPONENTS}, "connectivity": ComponentHealth(True),
            "can_bus": ComponentHealth(True)}


@dataclass
class RecordingPort:
    """A `RobotPort` whose answers are plain attributes and whose commands are recorded.

    ``yaw_per_command`` integrates commanded turn rates into ``current_pose`` (``dt_s`` per command), so a
    Rotate leaf sees its own motion; leave it 0 to keep the pose fixed.
    """

    components: dict[str, ComponentHealth] = field(default_factory=all_healthy)
    current_pose: Pose2D | None = field(default_factory=Pose2D)
    joystick_command: tuple[Twist, float] | None = None
    is_localized: bool | None = None
    #: The localizer's state while not localized ("lost" unless set: "ambiguous", "searching", ...).
    unlocalized_state: LocalizationState = "lost"
    #: What `wants_a_look` answers (the operator's FIND POSITION is ambiguous).
    look_asked: bool = False
    mapping_available: bool = False
    camera_ok: bool = True
    dt_s: float = 0.0
    commands: list[tuple[VelocitySource, Twist, float]] = field(default_factory=list)
    stops: int = 0
    modes: list[Mode] = field(default_factory=list)
    images: list[str] = field(default_factory=list)
    maps: list[str | None] = field(default_factory=list)
    relocalizations: list[float] = field(default_factory=list)
    mapping: bool = False
    #: What `clear_faults` answers (None: cleared); every call is counted in ``fault_clears``.
    faults_latched: str | None = None
    fault_clears: int = 0
    #: What `battery` answers (None: no reading); every `report` is kept in ``reports``.
    battery_status: BatteryStatus | None = None
    reports: list[tuple[str, str]] = field(default_factory=list)

    def command_velocity(self, source: VelocitySource, twist: Twist, now: float) -> None:
        self.commands.append((source, twist, now))
        if self.dt_s and self.current_pose is not None:
            p = self.current_pose
            self.current_pose = Pose2D(p.x_m, p.y_m, p.yaw_rad + twist.angular_radps * self.dt_s)

    def stop_motors(self) -> None:
        self.stops += 1

    def set_mode(self, mode: Mode) -> None:
        self.modes.append(mode)

    def health(self) -> Mapping[str, ComponentHealth]:
        return dict(self.components)

    def pose(self) -> Pose2D | None:
        return self.current_pose

    def odom_pose(self) -> Pose2D | None:
        return self.current_pose

    def joystick(self) -> tuple[Twist, float] | None:
        return self.joystick_command

    def capture_image(self, label: str) -> str:
        if not self.camera_ok:
            raise HardwareError("no frame", component="camera")
        path = f"images/{label}-{len(self.images)}.jpg"
        self.images.append(path)
        return path

    def localization_status(self) -> LocalizationStatus | None:
        if self.is_localized is None:
            return None
        return LocalizationStatus(0.95 if self.is_localized else 0.0, 0.7,
                                  "localized" if self.is_localized else self.unlocalized_state)

    def wants_a_look(self) -> bool:
        return self.look_asked

    def relocalize(self, now: float) -> None:
        if self.is_localized is None:
            raise NavigationError("localization is not available in this build")
        self.relocalizations.append(now)
        self.is_localized = False

    def begin_mapping(self) -> None:
        if not self.mapping_available:
            raise NavigationError("mapping is not available in this build")
        self.mapping = True

    def end_mapping(self, save_as: str | None) -> None:
        self.mapping = False
        self.maps.append(save_as)

    def clear_faults(self) -> str | None:
        self.fault_clears += 1
        return self.faults_latched

    def battery(self) -> BatteryStatus | None:
        return self.battery_status

    def report(self, kind: str, text: str) -> None:
        self.reports.append((kind, text))

    @property
    def last_twist(self) -> Twist | None:
        return self.commands[-1][1] if self.commands else None


@dataclass
class RecordingLink:
    """A `LinkPort` that records what the agent sends (stamped by ``time_source``); a test sets ``heartbeat``
    and ``power_off``."""

    heartbeat: bool = True
    power_off: bool = False
    time_source: Callable[[], float] = field(default=lambda: 0.0)
    statuses: list[tuple[float, PrimaryStatus]] = field(default_factory=list)
    power_states: list[tuple[float, PowerState]] = field(default_factory=list)

    def publish_status(self, status: PrimaryStatus) -> None:
        self.statuses.append((self.time_source(), status))

    def set_power_state(self, state: PowerState) -> None:
        self.power_states.append((self.time_source(), state))

    def power_off_requested(self) -> bool:
        return self.power_off

    def heartbeat_ok(self) -> bool:
        return self.heartbeat


@dataclass
class StraightLineNavigation:
    """A `NavigationPort` that drives ``port``'s pose in straight lines (through the route's points, if any)
    to the goal at ``speed_mps`` per second of ``update`` time, then turns to the goal heading: no map, no
    obstacles, just the contract.

    ``refuse`` makes `check_goal`/`start` refuse with that reason; ``fail_after_s`` makes a goal fail with
    ``"stuck"`` after that long. Records every goal started (``goals``), its route (``routes``) and every
    cancel.
    """

    port: RecordingPort
    speed_mps: float = 0.5
    tolerance_m: float = 0.05
    refuse: str | None = None
    fail_after_s: float | None = None
    goals: list[Pose2D] = field(default_factory=list)
    routes: list[list[tuple[float, float]] | None] = field(default_factory=list)
    cancels: list[float] = field(default_factory=list)
    #: The named places `places` answers (``GoToPlace`` looks them up).
    known_places: Places = field(default_factory=Places)
    _goal: Pose2D | None = field(default=None, init=False)
    _via: list[tuple[float, float]] = field(default_factory=list, init=False)
    _t: float = field(default=0.0, init=False)
    _started: float = field(default=0.0, init=False)
    _state: NavState = field(default="IDLE", init=False)

    def check_goal(self, goal: Pose2D) -> str | None:
        return self.refuse

    def start(self, goal: Pose2D, now: float, route: Sequence[Sequence[float]] | None = None) -> None:
        if self.refuse is not None:
            raise NavigationError(self.refuse)
        via = None if route is None else [(float(p[0]), float(p[1])) for p in route]
        self.goals.append(goal)
        self.routes.append(via)
        self._via = list(via or [])
        self._goal, self._t, self._started, self._state = goal, now, now, "RUNNING"

    def update(self, now: float) -> NavProgress:
        if self._state != "RUNNING" or self._goal is None or self.port.current_pose is None:
            return NavProgress(self._state)
        if self.fail_after_s is not None and now - self._started >= self.fail_after_s:
            self._state = "FAILED"
            return NavProgress("FAILED", reason="stuck")
        dt, self._t = now - self._t, now
        p, g = self.port.current_pose, self._goal
        tx, ty = self._via[0] if self._via else (g.x_m, g.y_m)
        dx, dy = tx - p.x_m, ty - p.y_m
        left = math.hypot(dx, dy)
        step = min(left, self.speed_mps * dt)
        if left > self.tolerance_m:
            x, y = p.x_m + dx / left * step, p.y_m + dy / left * step
            self.port.current_pose = Pose2D(x, y, p.yaw_rad)
            return NavProgress("RUNNING", Twist(self.speed_mps, 0.0), left - step, (left - step) / self.speed_mps)
        if self._via:
            self._via.pop(0)
            self.port.current_pose = Pose2D(tx, ty, p.yaw_rad)
            return NavProgress("RUNNING", Twist(self.speed_mps, 0.0), math.nan, math.nan)
        self.port.current_pose = Pose2D(g.x_m, g.y_m, g.yaw_rad)
        self._state = "SUCCEEDED"
        return NavProgress("SUCCEEDED", distance_left_m=0.0)

    def places(self) -> Places:
        return self.known_places

    def cancel(self, now: float) -> None:
        self.cancels.append(now)
        if self._state == "RUNNING":
            self._state = "CANCELED"
