"""Socket.IO events of the Agent studio: confirm or deny a transition waiting for the operator, set the
robot's autonomy level, reload the agent document now.

Role-checked like every event (`atemr.ui.sockets.EventGroup`); the confirming user's name goes to the robot
and into the agent's transition trace.
"""

from __future__ import annotations

from typing import Any

from atemr.errors import ProtocolError
from atemr.fsm.autonomy import LEVELS
from atemr.ui import payload
from atemr.ui.gateway import CommandResult, RobotGateway
from atemr.ui.security import current_user
from atemr.ui.sockets import EventGroup

events = EventGroup("agent")


def _request_id(event: str, data: Any) -> int:
    value = payload.mapping(event, data).get("id")
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ProtocolError(f"{event}.id: expected the pending request's id (a positive integer), got {value!r}")
    return value


def _user() -> str:
    user = current_user()
    return user.username if user is not None else "?"


@events.on("autonomy_confirm")
def autonomy_confirm(robot: RobotGateway, data: Any) -> CommandResult:
    """``{id}``: take the waiting transition."""
    return robot.answer_transition(_request_id("autonomy_confirm", data), True, _user())


@events.on("autonomy_deny")
def autonomy_deny(robot: RobotGateway, data: Any) -> CommandResult:
    """``{id}``: do not take it (the safe path: stay, or the transition's ``on_deny``)."""
    return robot.answer_transition(_request_id("autonomy_deny", data), False, _user())


@events.on("autonomy_level")
def autonomy_level(robot: RobotGateway, data: Any) -> CommandResult:
    """``{level: "off" | "low" | "high" | "full"}``."""
    level = payload.text("autonomy_level", data, "level")
    if level not in LEVELS:
        return CommandResult.refused(f"autonomy_level.level: one of {', '.join(LEVELS)}, got {level!r}")
    return robot.set_autonomy(level, _user())


@events.on("agent_reload", permission="agent_reload")
def agent_reload(robot: RobotGateway, data: Any) -> CommandResult:
    """Re-read the agent document now; the result and the diff appear on the Agent page."""
    return robot.reload_agent()
