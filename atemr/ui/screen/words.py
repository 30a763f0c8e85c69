"""What the robot does and how charged it is, in words a resident reads on the robot's screen from 1 to 2 m away.

The operator's pages show states and codes; the person at home needs one short sentence. Pure: it reads
a `RobotState` (or the part of it the robot sent) and never fails on a key that is missing or unknown.
The wording follows the robot's own plain words (`atemr.robot.plain_words`, the events and refusals),
which this layer may not import: the dashboard sits below the robot.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: Why the robot is held stopped (`RobotState.stop_cause`), as the resident reads it.
STOPPED = {
    "cliff": "Stopped: a step or stairs next to me",
    "floor_sensors": "Stopped: I cannot see the floor",
    "obstacle": "Stopped: something in front of me",
    "heartbeat": "Stopped: my two computers lost contact",
    "motor": "Stopped: a motor fault",
    "bus": "Stopped: my motors do not answer",
}

#: What each agent state means, when nothing more specific applies.
DOING = {
    "UNDEFINED": "Starting up",
    "STARTUP": "Starting up",
    "IDLE": "Waiting",
    "EXEC": "Busy with a task",
    "MAPPING": "Learning the rooms",
    "ERROR": "I have stopped: something is wrong",  # no promise of help: nobody may be watching the dashboard
    "SHUTDOWN": "Shutting down",
}


def plain_activity(state: Mapping[str, Any]) -> str:
    """One sentence for the screen: the reason it is stopped first, then the mission or goal, then the
    agent state."""
    cause = state.get("stop_cause")
    if cause:
        return STOPPED.get(str(cause), "Stopped")
    if state.get("emergency") is True:
        return "Stopped: emergency stop"
    agent = str(state.get("agent_state") or "UNDEFINED")
    mission = state.get("mission")
    if agent == "EXEC" and isinstance(mission, Mapping) and mission.get("name"):
        return f"Doing the task '{mission['name']}'"
    if agent == "EXEC" and state.get("goal"):
        return "Going to a goal"
    localization = state.get("localization")
    if agent == "IDLE" and isinstance(localization, Mapping) and localization.get("looking_around") is True:
        return "Turning to look around: finding where I am"  # it moves by itself: say why
    if agent == "IDLE" and state.get("mode") == "MANUAL":
        return "Waiting; someone can drive me from afar"
    return DOING.get(agent, "Waiting")


#: The battery's level (`RobotState.battery`), as the resident reads it beside the charge.
CHARGE = {
    "ok": "Battery {percent} %",
    "low": "Battery low: {percent} %",
    "return": "Battery {percent} %: I need to charge",
    "critical": "Battery {percent} %: please put me on my charger",
}


def plain_battery(state: Mapping[str, Any]) -> str:
    """The charge in a few words ("Battery 76 %"); "" before the robot has measured it."""
    battery = state.get("battery")
    if not isinstance(battery, Mapping) or not isinstance(battery.get("percent"), (int, float)):
        return ""
    text = CHARGE.get(str(battery.get("level")), CHARGE["ok"])
    return text.format(percent=round(battery["percent"]))
