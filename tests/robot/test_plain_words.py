"""Refusals and outcomes in the words a carer reads: no state names, no triggers, and what to do."""

from __future__ import annotations

import re
from typing import get_args

import pytest

from atemr.domain.status import LocalizationState, LocalizationStatus
from atemr.robot.plain_words import (
    ACTIONS,
    GOAL_REFUSALS,
    NAVIGATION_FAILURES,
    STATES,
    plain_goal_refusal,
    plain_guard_refusal,
    plain_outcome,
    plain_refusal,
)
from atemr.skills.nav.goal_check import GoalCheck, GoalRefusal
from atemr.skills.nav.navigator import FailReason, NavStatus

STATES_SEEN = ["STARTUP", "IDLE.MANUAL", "IDLE.AUTO", "EXEC", "MAPPING", "ERROR", "SHUTDOWN"]
TECHNICAL = re.compile(r"IDLE|EXEC|MAPPING|STARTUP|ERROR\b|SHUTDOWN|'[a-z_]+'|valid here|_")


@pytest.mark.parametrize("state", STATES_SEEN)
@pytest.mark.parametrize("trigger", sorted(ACTIONS))
def test_every_refusal_is_a_plain_sentence(trigger, state):
    text = plain_refusal(trigger, state)
    assert text[0].isupper() and text.endswith("."), text
    assert not TECHNICAL.search(text.replace("AUTO", "").replace("MANUAL", "")), text


def test_refusals_say_what_to_do():
    assert plain_refusal("goal", "IDLE.MANUAL") == "Cannot drive to a goal in MANUAL: switch to AUTO first."
    assert "end the map first" in plain_refusal("goal", "MAPPING.MANUAL")
    assert "cancel it first" in plain_refusal("begin_mapping", "EXEC")
    assert "nothing to cancel" in plain_refusal("cancel", "IDLE.AUTO")
    assert set(STATES) >= {s.split(".")[0] for s in STATES_SEEN}


def test_outcomes_of_goals_and_missions():
    assert plain_outcome({"mission": "goal", "outcome": "reached"}) == ("goal", "Goal reached.")
    assert plain_outcome({"mission": "goal", "outcome": "failed", "reason": "no path"}) == (
        "goal", "Goal failed: no path.")
    assert plain_outcome({"mission": "patrol", "outcome": "reached"}) == ("mission", "Mission 'patrol' finished.")
    assert plain_outcome({"mission": "patrol", "outcome": "cancelled", "reason": "stopped by the operator"}) == (
        "mission", "Mission 'patrol' cancelled: stopped by the operator.")


def test_a_mission_the_navigator_failed_names_its_step_and_says_why() -> None:
    message = "no path: no path to the goal after recoveries (clear costmap, rotate in place, back off, replan)"
    report = {"mission": "map-the-flat", "outcome": "failed",
              "reason": f"the other rooms: waypoint 3: navigation failed: {message}"}
    kind, text = plain_outcome(report, NavStatus("FAILED", reason="no path", message=message))
    assert (kind, text) == ("mission", "Mission 'map-the-flat' failed at the other rooms: waypoint 3: "
                                       + NAVIGATION_FAILURES["no path"])
    assert "navigation failed" not in text and "recoveries" not in text


@pytest.mark.parametrize("outcome", ["fault", "power_off", "shutdown", "restart"])
def test_a_task_a_fault_or_a_shutdown_ended_is_said_as_stopped(outcome: str) -> None:
    for mission, start in (("goal", "Goal stopped: "), ("patrol", "Mission 'patrol' stopped: ")):
        _, text = plain_outcome({"mission": mission, "outcome": outcome, "reason": "0x157 heartbeat lost"})
        assert text.startswith(start) and text.endswith("."), text
        assert "0x157" not in text and not TECHNICAL.search(text.replace("'patrol'", "")), text


@pytest.mark.parametrize("code", [c for c in get_args(GoalRefusal) if c not in ("not finite", "not AUTO mode")])
def test_every_goal_refusal_is_said_on_the_map_with_what_to_do(code):
    """The navigator's words ("goal (2.30, 2.57, 0.00 rad) is 0.25 m from an obstacle of map 'studio'; ...") stay
    in the log; the carer reads what the spot is and what to tap. (A goal that is not finite or sent in MANUAL is
    answered before the navigator is asked.)"""
    status = LocalizationStatus(0.3, 0.7, "lost")
    text = plain_goal_refusal(GoalCheck(False, code, "goal (2.30, 2.57, 0.00 rad) is ... of map 'studio'"), status)
    assert text[0].isupper() and text.endswith("."), text
    assert "goal (" not in text and not TECHNICAL.search(text.replace("SET POSITION", "")), text
    assert code == "not localized" or code in GOAL_REFUSALS


def test_a_goal_refusal_without_a_code_is_already_plain():
    no_map = "no map is selected: select a map (or make one in MAPPING) and set the robot's pose first"
    assert plain_goal_refusal(GoalCheck(False, None, no_map), LocalizationStatus(0.0, 0.7, "no map")) == no_map


@pytest.mark.parametrize("why", get_args(FailReason))
def test_a_goal_the_navigator_gave_up_is_said_by_why(why):
    message = f"{why}: goal not reached within 12 s"
    report = {"mission": "goal", "outcome": "failed",
              "reason": f"goal 0: (2.40, 3.40, 0.00): navigation failed: {message}"}
    kind, text = plain_outcome(report, NavStatus("FAILED", reason=why, message=message))
    assert kind == "goal" and text == f"Goal failed: {NAVIGATION_FAILURES[why]}"
    assert "goal 0" not in text and "navigation failed" not in text and text.endswith("."), text
    # another goal's failure (its message is not this report's) is not taken for this one's
    assert plain_outcome(report, NavStatus("FAILED", reason=why, message="stuck: earlier")) == (
        "goal", f"Goal failed: {report['reason']}.")


NOT_LOCALIZED: list[LocalizationState] = [s for s in get_args(LocalizationState) if s != "localized"]


@pytest.mark.parametrize("state", NOT_LOCALIZED)
@pytest.mark.parametrize("trigger", ["set_auto", "start_mission"])
def test_a_robot_that_does_not_know_where_it_is_says_so_and_what_to_do(trigger, state):
    """Issue 21: AUTO and missions wait for a pose; the carer reads why and what to do, never the guard's terms."""
    status = LocalizationStatus(0.4, 0.7, state)
    text = plain_guard_refusal(trigger, "level-1 status not OK (not localized (...))", status)
    assert text.startswith(f"Cannot {ACTIONS[trigger]}: ") and text.endswith("."), text
    assert "SET POSITION" in text or "Mapping page" in text, text
    assert "level-1" not in text and not TECHNICAL.search(text.replace("AUTO", "").replace("SET POSITION", "")), text


def test_other_guard_refusals_keep_the_guards_reason():
    localized = LocalizationStatus(0.9, 0.7, "localized")
    assert plain_guard_refusal("set_auto", "level-1 status not OK (unhealthy: lidar)", localized) == (
        "Cannot switch to AUTO now: level-1 status not OK (unhealthy: lidar).")
    lost = plain_guard_refusal("set_auto", "...", LocalizationStatus(0.42, 0.7, "lost"))
    assert "(42% sure, it needs 70%)" in lost and "FIND POSITION" in lost
