"""Refusals and outcomes in the words a carer reads: no state names, no triggers, and what to do."""

from __future__ import annotations

import re
from typing import get_args

import pytest

from atemr.domain.status import LocalizationState, LocalizationStatus
from atemr.robot.plain_words import ACTIONS, STATES, plain_guard_refusal, plain_outcome, plain_refusal

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
