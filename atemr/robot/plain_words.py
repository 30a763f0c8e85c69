"""What the robot tells a carer, in plain words: refusals and the outcomes of goals and missions.

The agent speaks in states and triggers ("'cancel' is not valid in state IDLE.MANUAL (valid here: ...)");
that stays on the Agent page, for the engineer. The dashboard's other pages show what a carer can act on:
what could not be done, why, and what to do instead. Pure functions, no I/O.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from atemr.domain.status import LocalizationStatus
from atemr.trees.missions import GOAL_TASK

if TYPE_CHECKING:  # types only: the navigator's module loads the planners
    from atemr.skills.nav.goal_check import GoalCheck, GoalRefusal
    from atemr.skills.nav.navigator import FailReason, NavStatus

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


def plain_unconfirmed(trigger: str, decision: str, by: str) -> str:
    """Why a step the robot asked the operator about (its autonomy level) was not taken: ``decision`` is
    "timed_out" (nobody answered) or "denied" (by ``by``)."""
    action = ACTIONS.get(trigger, trigger.replace("_", " "))
    why = "nobody confirmed it in time" if decision == "timed_out" else f"{by} denied it"
    return f"The robot did not {action}: {why}. It stays where it is."


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


def plain_guard_refusal(trigger: str, why: str, localization: LocalizationStatus) -> str:
    """Why the agent's guards refuse ``trigger`` now, as a carer reads it. The guards decide (``why``, in the
    agent's words); a robot that does not know where it is is said plainly with what to do, because that is
    the refusal a carer meets most (after a map switch, a kidnap) and can mend at once. Any other reason (a
    part unhealthy, the heartbeat lost) is the guard's own sentence, which the level-1 lights show too."""
    action = ACTIONS.get(trigger, trigger.replace("_", " "))
    if not localization.localized:
        return f"Cannot {action}: {plain_not_localized(localization)}"
    return f"Cannot {action} now: {why}."


def plain_not_localized(status: LocalizationStatus) -> str:
    """What a robot that is not localized means for the carer, and what to do (one sentence or two)."""
    if status.state == "no map":
        return "no map is chosen. Choose or make one on the Mapping page, then set the robot's position on it."
    if status.state == "ambiguous":
        return ("places on the map look alike to the robot (drawn on the map). Drive it a little so that it can "
                "tell them apart, or set its position on the map (SET POSITION).")
    if status.state in ("searching", "pose set"):
        return ("the robot is still working out where it is. Wait a moment, or set its position on the map "
                "(SET POSITION).")
    return (f"the robot is not sure where it is ({status.confidence:.0%} sure, it needs {status.limit:.0%}). Set its "
            "position on the map (SET POSITION) or press FIND POSITION.")


#: What a goal refused by the navigator's checks (`atemr.skills.nav.goal_check`) means on the map, and what to do.
GOAL_REFUSALS: dict[GoalRefusal, str] = {
    "outside the map": "That spot is outside the map. Tap a spot on the map.",
    "in an obstacle": "That spot is inside a wall or a piece of furniture on the map. Tap a free spot.",
    "too close to an obstacle": "That spot is too close to a wall or a piece of furniture for the robot to stand "
                                "there. Tap a spot further from it.",
    "in unknown space": "That spot is not mapped (grey on the map). Tap a spot in the mapped part.",
}

#: Why the navigator gave a goal up (`atemr.skills.nav.navigator.FailReason`), and what to do.
NAVIGATION_FAILURES: dict[FailReason, str] = {
    "no path": "the way there is blocked. Clear the way, or send the robot somewhere else.",
    "stuck": "the robot got stuck on the way. Look at the camera, drive it free in MANUAL, then send it again.",
    "localization lost": "the robot lost track of where it is. Set its position (SET POSITION) or press FIND "
                         "POSITION, then send it again.",
    "timeout": "the robot did not get there in time; something may be in the way. Look at the camera, then send "
               "it again.",
}


def plain_goal_refusal(check: GoalCheck, localization: LocalizationStatus) -> str:
    """Why the goal ``check`` refused cannot be driven to, as a carer reads it (the page puts "Go here: " first).
    Refusals without a code of their own (no map yet) are already a carer's sentence."""
    if check.code == "not localized":
        return f"Cannot drive to a goal: {plain_not_localized(localization)}"
    said = GOAL_REFUSALS.get(check.code) if check.code is not None else None
    return said or check.reason


#: Why a task ended without succeeding or failing (the agent's trigger that left EXEC), as a carer reads it.
INTERRUPTIONS = {
    "fault": "stopped: the robot has a fault (its alert says which and what to do). Send it again once the fault "
             "is gone",
    "power_off": "stopped: the robot is powering off",
    "shutdown": "stopped: the robot is shutting down",
    "restart": "stopped: the robot is restarting",
}


def plain_outcome(report: dict[str, Any], navigation: NavStatus | None = None) -> tuple[str, str]:
    """The event (kind, text) for a finished goal or mission (`atemr.trees.progress.TaskProgress.report`).

    ``navigation``: the navigator's last status; when it is the failure this task ended with (its message is
    in the report's reason), the failure is said by the navigator's `FailReason`, not in the task's words
    ("goal 0: (2.40, 3.40, 0.00): navigation failed: timeout: ..."); a mission names the step it failed at.
    A task a fault or a shutdown ended is said as stopped, not by the agent's trigger."""
    outcome = str(report.get("outcome") or "finished")
    reason = str(report.get("reason") or "")
    failure = None
    if outcome == "failed" and navigation is not None and navigation.state == "FAILED" and navigation.message \
            and navigation.message in reason:
        failure = navigation.reason
    if report.get("mission") == GOAL_TASK:  # a single goal from the dashboard (`atemr.trees.missions.goal_task`)
        if failure is not None:
            return "goal", f"Goal failed: {NAVIGATION_FAILURES[failure]}"
        if outcome in INTERRUPTIONS:
            return "goal", f"Goal {INTERRUPTIONS[outcome]}."
        text = {"reached": "Goal reached.", "cancelled": "Goal cancelled."}.get(outcome, f"Goal {outcome}")
        if outcome not in ("reached", "cancelled"):
            text += f": {reason}." if reason else "."
        return "goal", text
    name = report.get("mission") or "mission"
    if outcome == "reached":  # every step done
        return "mission", f"Mission '{name}' finished."
    if failure is not None:
        step, _, _ = reason.partition(": navigation failed")
        return "mission", f"Mission '{name}' failed at {step.strip()}: {NAVIGATION_FAILURES[failure]}"
    if outcome in INTERRUPTIONS:
        return "mission", f"Mission '{name}' {INTERRUPTIONS[outcome]}."
    text = f"Mission '{name}' {outcome}" + (f": {reason}." if reason else ".")
    return "mission", text
