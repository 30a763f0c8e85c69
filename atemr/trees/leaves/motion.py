"""Leaves that move or stop the base. Every one that commands a velocity commands zero in ``terminate``,
so an interrupted or finished motion never leaves a twist behind in the mux."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import py_trees

from atemr.msgs import ZERO_TWIST, Twist
from atemr.trees.behaviours import Leaf, behaviours

Status = py_trees.common.Status


def wrap_angle(angle_rad: float) -> float:
    """``angle_rad`` folded into [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


@behaviours.register("StopMotors")
class StopMotors(Leaf):
    """Stop the base at once (joystick, navigation and agent inputs to zero); always SUCCESS."""

    summary = "command zero velocity on the joystick, navigation and agent inputs"

    def update(self) -> py_trees.common.Status:
        self.ctx.port.stop_motors()
        return Status.SUCCESS


@dataclass(frozen=True)
class DriveJoystickParams:
    timeout_s: float = field(default=0.5, metadata={"min": 0.05, "max": 5.0})
    #: Turn rate of the look around after an ambiguous FIND POSITION (0: never turn by itself).
    look_speed_radps: float = field(default=0.4, metadata={"min": 0.0, "max": 1.6})


@behaviours.register("DriveJoystick")
class DriveJoystick(Leaf):
    """Forward the operator's joystick to the mux's joystick input while the state lasts (MANUAL, MAPPING).

    A joystick command older than ``timeout_s`` is replaced by zero (the thesis' lost-browser-tab rule,
    applied here as well as in the mux). Never finishes on its own: RUNNING until the state ends.

    The operator who pressed FIND POSITION asked the robot to find itself: while that search is ambiguous and
    asks for it (`RobotPort.wants_a_look`), the robot turns in place at ``look_speed_radps`` so the lidar's views
    tell the look-alike places apart (issue 21: "rotate in place ... when the operator asks"). The localizer
    ends the look: after about one revolution, after `LOOK_TIMEOUT_S`, or when the operator takes over (the
    joystick, STOP or mapping: the gateway tells it), so the robot never starts turning again by itself. The
    turn is the operator's own request, so it goes out on the joystick input, under the safety stop like any
    driving. ``look_speed_radps: 0`` (the MAPPING state's) never turns.
    """

    Params = DriveJoystickParams
    summary = "pass the operator's joystick to the base until the state ends (turning to look after FIND POSITION)"

    def update(self) -> py_trees.common.Status:
        latest = self.ctx.port.joystick()
        twist, stamp = ZERO_TWIST, self.ctx.now
        if latest is not None and self.ctx.now - latest[1] <= self.params.timeout_s:
            # Forward the operator's own time stamp, not ours: the mux then expires a lost browser tab's
            # last command on time and stops hard (watchdog), instead of ramping down from a fresh zero.
            twist, stamp = latest
        elif self.params.look_speed_radps and self.ctx.port.wants_a_look():
            twist = Twist(0.0, self.params.look_speed_radps)
        self.feedback_message = f"v={twist.linear_mps:.2f} m/s w={twist.angular_radps:.2f} rad/s"
        if stamp == self.ctx.now and twist.angular_radps:
            self.feedback_message += " (looking around)"
        self.ctx.port.command_velocity("joystick", twist, stamp)
        return Status.RUNNING

    def terminate(self, new_status: py_trees.common.Status) -> None:
        if self._context is not None:
            self.ctx.port.command_velocity("joystick", ZERO_TWIST, self.ctx.now)


@dataclass(frozen=True)
class RotateParams:
    angle_rad: float = field(default=0.0, metadata={"min": -4 * math.pi, "max": 4 * math.pi, "required": True})
    tolerance_rad: float = field(default=0.05, metadata={"min": 0.005, "max": 0.5})
    max_speed_radps: float = field(default=0.8, metadata={"min": 0.05, "max": 1.6})
    gain: float = field(default=1.5, metadata={"min": 0.1, "max": 10.0})


@behaviours.register("Rotate")
class Rotate(Leaf):
    """Turn in place by ``angle_rad`` (counter-clockwise positive) using the odometry's heading as feedback (a
    turn relative to where the robot stands needs no map: it works while the robot is not localized).

    A proportional controller on the remaining angle, saturated at ``max_speed_radps``; the remaining
    angle is integrated from heading changes so turns beyond half a revolution work. SUCCESS within
    ``tolerance_rad``; FAILURE when there is no pose to steer by. Commands on the pipeline's ``agent``
    input (the agent's own motions, admitted in MANUAL and AUTO above navigation).
    """

    Params = RotateParams
    summary = "rotate in place by angle_rad using heading feedback"

    def initialise(self) -> None:
        pose = self.ctx.port.odom_pose()
        self._last_yaw = pose.yaw_rad if pose is not None else None
        self._remaining = self.params.angle_rad

    def update(self) -> py_trees.common.Status:
        pose = self.ctx.port.odom_pose()
        if pose is None or self._last_yaw is None:
            return self.fail("no pose to steer by")
        self._remaining -= wrap_angle(pose.yaw_rad - self._last_yaw)
        self._last_yaw = pose.yaw_rad
        self.feedback_message = f"{math.degrees(self._remaining):.1f} deg left"
        if abs(self._remaining) <= self.params.tolerance_rad:
            self.ctx.port.command_velocity("agent", ZERO_TWIST, self.ctx.now)
            return Status.SUCCESS
        limit = self.params.max_speed_radps
        speed = max(-limit, min(limit, self.params.gain * self._remaining))
        self.ctx.port.command_velocity("agent", Twist(0.0, speed), self.ctx.now)
        return Status.RUNNING

    def terminate(self, new_status: py_trees.common.Status) -> None:
        if self._context is not None:
            self.ctx.port.command_velocity("agent", ZERO_TWIST, self.ctx.now)
