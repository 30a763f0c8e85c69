"""Socket.IO events of the Control page: drive, mode, goals, media, missions and the simulation panel.

Each returns the robot's `CommandResult`; payloads are checked by `atemr.ui.payload` first.
"""

from __future__ import annotations

from typing import Any

from atemr.domain.places import MAX_NAME_CHARS
from atemr.msgs import Twist
from atemr.ui import payload
from atemr.ui.gateway import CommandResult, RobotGateway
from atemr.ui.sockets import EventGroup

#: Largest speeds a joystick event may ask for; the robot clamps to its own (lower) limits.
MAX_JOYSTICK_LINEAR_MPS = 2.0
MAX_JOYSTICK_ANGULAR_RADPS = 4.0

events = EventGroup("control")


@events.on("joystick")
def joystick(robot: RobotGateway, data: Any) -> CommandResult:
    """``{linear_mps, angular_radps}``: sent at 10 Hz while the stick is held (the robot's 0.5 s timeout)."""
    lin = payload.number("joystick", data, "linear_mps", lo=-MAX_JOYSTICK_LINEAR_MPS, hi=MAX_JOYSTICK_LINEAR_MPS)
    ang = payload.number("joystick", data, "angular_radps", lo=-MAX_JOYSTICK_ANGULAR_RADPS,
                         hi=MAX_JOYSTICK_ANGULAR_RADPS)
    return robot.joystick(Twist(lin, ang))


@events.on("mode")
def mode(robot: RobotGateway, data: Any) -> CommandResult:
    """``{mode: "MANUAL" | "AUTO"}``."""
    value = payload.text("mode", data, "mode")
    if value == "MANUAL":
        return robot.set_mode("MANUAL")
    if value == "AUTO":
        return robot.set_mode("AUTO")
    return CommandResult.refused(f"unknown mode {value!r}: MANUAL or AUTO")


@events.on("goal")
def goal(robot: RobotGateway, data: Any) -> CommandResult:
    """``{x_m, y_m, yaw_rad}`` in the map frame."""
    return robot.set_goal(payload.pose("goal", data))


@events.on("go_to_place")
def go_to_place(robot: RobotGateway, data: Any) -> CommandResult:
    """``{name}``: a named place of the active map (the "Go to" list)."""
    return robot.go_to_place(payload.text("go_to_place", data, "name", max_len=MAX_NAME_CHARS))


@events.on("initial_pose")
def initial_pose(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.set_initial_pose(payload.pose("initial_pose", data))


@events.on("localize_globally")
def localize_globally(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.localize_globally()


@events.on("cancel_goal")
def cancel_goal(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.cancel_goal()


@events.on("capture_image")
def capture_image(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.capture_image()


@events.on("record_video")
def record_video(robot: RobotGateway, data: Any) -> CommandResult:
    """``{on: bool}``."""
    return robot.record_video(payload.flag("record_video", data, "on"))


@events.on("mission_start")
def mission_start(robot: RobotGateway, data: Any) -> CommandResult:
    """``{name}``: one of the state's ``missions``."""
    return robot.start_mission(payload.text("mission_start", data, "name"))


@events.on("mission_stop")
def mission_stop(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.stop_mission()


@events.on("sim_button", permission="power")
def sim_button(robot: RobotGateway, data: Any) -> CommandResult:
    """``{hold_s}``: press the secondary core's button (simulation only)."""
    return robot.sim_button(payload.number("sim_button", data, "hold_s", lo=0.05, hi=15.0))


@events.on("sim_obstacle")
def sim_obstacle(robot: RobotGateway, data: Any) -> CommandResult:
    """``{x_m, y_m}``: drop an obstacle in the simulated world."""
    x = payload.number("sim_obstacle", data, "x_m", lo=-1e6, hi=1e6)
    y = payload.number("sim_obstacle", data, "y_m", lo=-1e6, hi=1e6)
    return robot.sim_drop_obstacle(x, y)


@events.on("sim_kidnap")
def sim_kidnap(robot: RobotGateway, data: Any) -> CommandResult:
    """``{x_m, y_m, yaw_rad}``: move the simulated robot behind its localization's back."""
    return robot.sim_kidnap(payload.pose("sim_kidnap", data))
