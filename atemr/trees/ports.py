"""The agent's only doors to the robot: two small typed ports the lead engineer implements.

Leaves, guards and callbacks never import a driver, a skill or the CAN bus; they call a `RobotPort`
(motion, health, pose, camera, mapping) and a `LinkPort` (the primary's side of the secondary-core link:
0x153 status out, 0x150 power byte, power-off requests and heartbeat health in). That keeps the agent
testable with an in-test fake and lets the real parts land behind the ports without the agent changing.

A method that cannot answer yet (no localization in this build) returns ``None`` rather than guessing.
Navigation is a third, optional port (`NavigationPort`): without it goals and missions that drive to a pose
are refused with that reason; with it, its goal check is the one the agent uses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, Protocol, runtime_checkable

from atemr.domain.places import Places
from atemr.domain.status import BatteryStatus, ComponentHealth, HardwareBits, LocalizationStatus, PowerState
from atemr.io.can import PrimaryStatus
from atemr.msgs import ZERO_TWIST, Pose2D, Twist

#: The motion pipeline's inputs the agent may command (`atemr.skills.motion_pipeline`): the operator's
#: joystick (MANUAL), navigation (AUTO: GoToPose), and ``agent`` for the agent's own motions (Rotate),
#: admitted in both modes above navigation. The safety stop and the reactive engine are never the agent's.
VelocitySource = Literal["joystick", "navigation", "agent"]
Mode = Literal["MANUAL", "AUTO"]

#: Components whose health fills a 0x153 hardware bit: ``HardwareBits`` member names in lower case
#: (``left_motor``, ``right_motor``, ``imu``, ``lidar``, ``camera``, ``webserver``, ``ir_front``, ``ir_rear``).
HARDWARE_COMPONENTS: dict[str, HardwareBits] = {str(b.name).lower(): b for b in HardwareBits if b}


@runtime_checkable
class RobotPort(Protocol):
    """What the agent asks of the robot. Times are the agent's injected ``now`` (seconds)."""

    def command_velocity(self, source: VelocitySource, twist: Twist, now: float) -> None:
        """Offer ``twist`` to the twist mux as input ``source`` (it expires there after its timeout)."""
        ...

    def stop_motors(self) -> None:
        """Command zero on the joystick, navigation and agent inputs at once."""
        ...

    def set_mode(self, mode: Mode) -> None:
        """Switch the twist mux between MANUAL (joystick wins) and AUTO (navigation wins)."""
        ...

    def health(self) -> Mapping[str, ComponentHealth]:
        """Every known component's health by name (names as in `HARDWARE_COMPONENTS`, plus any others)."""
        ...

    def pose(self) -> Pose2D | None:
        """Where the robot is on the map; None while it is not localized. Never a pose in another frame: a
        mission's steps, its final pose and the recording's poses are read as places on the map."""
        ...

    def odom_pose(self) -> Pose2D | None:
        """The odometry pose (the ``odom`` frame: smooth, drifts slowly, known while not localized): feedback for
        motions relative to where the robot stands, such as turning in place; None before any."""
        ...

    def joystick(self) -> tuple[Twist, float] | None:
        """The operator's latest joystick command and the time it arrived, or None if none yet."""
        ...

    def capture_image(self, label: str) -> str:
        """Store one camera frame and return where (a path or media id); raises `HardwareError`."""
        ...

    def localization_status(self) -> LocalizationStatus | None:
        """The confidence number, its limit and the localizer's state; None when this robot cannot localize at
        all. Its ``localized`` is the 0x153 LOCALIZATION bit and what the guards and leaves wait for."""
        ...

    def relocalize(self, now: float) -> None:
        """Start global relocalization on the active map (`Localizer.start_global`); raises an `AtemrError`
        when this robot cannot localize."""
        ...

    def wants_a_look(self) -> bool:
        """Whether the operator's FIND POSITION answered *ambiguous*, so the robot should turn in place to see
        more (`LocalizationPipeline.wants_a_look`); False when this robot cannot localize."""
        ...

    def begin_mapping(self) -> None:
        """Start SLAM; raises an `AtemrError` (e.g. `NavigationError`) when mapping is not available."""
        ...

    def end_mapping(self, save_as: str | None) -> None:
        """Stop SLAM and save the map as ``save_as`` (it becomes active) or discard it (None)."""
        ...

    def clear_faults(self) -> str | None:
        """Clear the recoverable hardware faults whose cause is gone (on the robot: reset the motor driver's
        latched fault once both motors answer again with no error flag). None when nothing is latched any
        more; otherwise why not yet (the Error state calls this while it waits for the cause to clear)."""
        ...

    def battery(self) -> BatteryStatus | None:
        """The state of charge with the limits the robot reacts at (the Monitor's ``WatchBattery``); None before
        the first good reading, or on a robot that cannot measure its battery."""
        ...

    def report(self, kind: str, text: str) -> None:
        """Tell the operator something that is not a transition (a battery warning): a robot event, which the
        dashboard's events and alerts and the recording show."""
        ...


@runtime_checkable
class LinkPort(Protocol):
    """The agent's view of the secondary-core link (the link itself sends the 0x157 heartbeat)."""

    def publish_status(self, status: PrimaryStatus) -> None:
        """Send CAN 0x153 now (agent bits, hardware bits, state code)."""
        ...

    def set_power_state(self, state: PowerState) -> None:
        """Set 0x150 byte 0 (1 after start-up, 2 to acknowledge power-off) and send it."""
        ...

    def power_off_requested(self) -> bool:
        """True once the secondary core has asked to power off (0x150 byte 1 = 1)."""
        ...

    def heartbeat_ok(self) -> bool:
        """True while the 0x157 exchange is alive (a valid answer within the last 2 s)."""
        ...


NavState = Literal["IDLE", "RUNNING", "SUCCEEDED", "FAILED", "CANCELED"]


@dataclass(frozen=True)
class NavProgress:
    """One navigation tick, as the `GoToPose` leaf needs it: the twist to command while RUNNING, feedback
    for the operator, and why it failed."""

    state: NavState
    twist: Twist = ZERO_TWIST
    distance_left_m: float = math.nan
    eta_s: float = math.nan
    reason: str = ""


@runtime_checkable
class NavigationPort(Protocol):
    """Go-to-pose on the active map (over `atemr.skills.nav.navigator.Navigator` on the robot).

    The port feeds the navigator the pose, scan and localization itself; the leaf commands the returned
    twist on the mux's navigation input, so the agent's zero-in-terminate rule covers navigation too.
    """

    def check_goal(self, goal: Pose2D) -> str | None:
        """None when ``goal`` would be accepted now (finite, localized, in the map, in free space), else why."""
        ...

    def start(self, goal: Pose2D, now: float, route: Sequence[Sequence[float]] | None = None) -> None:
        """Begin driving to ``goal`` (through the points ``[x_m, y_m]`` of ``route`` in order, when given);
        raises `NavigationError` with the reason when it is refused."""
        ...

    def update(self, now: float) -> NavProgress:
        """One navigation tick at ``now``."""
        ...

    def cancel(self, now: float) -> None:
        """Stop pursuing the goal (the next update is CANCELED)."""
        ...

    def places(self) -> Places:
        """The active map's named places (none without a map)."""
        ...
