"""What the robot tells a carer, in plain words: refusals and the outcomes of goals and missions.

The agent speaks in states and triggers ("'cancel' is not valid in state IDLE.MANUAL (valid here: ...)");
that stays on the Agent page, for the engineer. The dashboard's other pages show what a carer can act on:
what could not be done, why, and what to do instead. Pure functions, no I/O.
"""

from __future__ import annotations

from typing import Any

#: What each trigger the dashboard sends asks the robot to do.
ACTIONS = {
    "set_auto": "switch to AUTO",
    "set_manual": "switch to MANUAL",
    "goal": "drive to a goal",
    "cancel": "cancel",
    "begin_mapping": "start mapping",
    "end_mapping": "stop mapping",
    "save_map": "save the map",
    "discard_map": "discard the map",
    "start_mission": "start a mission",
}

#: What the robot is doing in each top-level state, and what the carer can do about it.
STATES = {
    "STARTUP": "the robot is still starting; wait a few seconds",
    "IDLE": "the robot is not doing anything",
    "EXEC": "the robot is busy with a goal or a mission; cancel it first",
    "MAPPING": "the robot is mapping; end the map first",
    "ERROR": "the robot has a fault (see the alerts); it recovers by itself when the cause is gone",
    "SHUTDOWN": "the robot is shutting down",
}


def plain_refusal(trigger: str, state: str) -> str:
    """Why ``trigger`` cannot be taken in ``state`` (e.g. ``IDLE.MANUAL``), as a carer reads it."""
    top, _, mode = state.partition(".")
    if trigger == "cancel" and top == "IDLE":
        return "There is nothing to cancel: the robot is not driving to a goal or running a mission."
    if trigger == "goal" and top == "IDLE" and mode == "MANUAL":
        return "Cannot drive to a goal in MANUAL: switch to AUTO first."
    if trigger == "start_mission" and top == "IDLE" and mode == "MANUAL":
        return "Cannot start a mission in MANUAL: switch to AUTO first."
    if trigger == "begin_mapping" and top == "IDLE" and mode == "AUTO":
        return "Cannot start mapping in AUTO: switch to MANUAL first and drive the robot round."
    if trigger in ("end_mapping", "save_map", "discard_map") and top != "MAPPING":
        return f"Cannot {ACTIONS[trigger]}: no map is being made."
    action = ACTIONS.get(trigger, trigger.replace("_", " "))
    doing = STATES.get(top, f"the robot is in state {top}")
    return f"Cannot {action} now: {doing}."


def plain_outcome(report: dict[str, Any]) -> tuple[str, str]:
    """The event (kind, text) for a finished goal or mission (`atemr.trees.progress.TaskProgress.report`)."""
    outcome = str(report.get("outcome") or "finished")
    reason = str(report.get("reason") or "")
    if report.get("mission") == "goal":  # a single goal from the dashboard (`atemr.trees.missions.goal_task`)
        text = {"reached": "Goal reached.", "cancelled": "Goal cancelled."}.get(outcome, f"Goal {outcome}")
        if outcome not in ("reached", "cancelled"):
            text += f": {reason}." if reason else "."
        return "goal", text
    name = report.get("mission") or "mission"
    if outcome == "reached":  # every step done
        return "mission", f"Mission '{name}' finished."
    text = f"Mission '{name}' {outcome}" + (f": {reason}." if reason else ".")
    return "mission", text
