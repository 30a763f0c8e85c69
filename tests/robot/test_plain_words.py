"""Refusals and outcomes in the words a carer reads: no state names, no triggers, and what to do."""

from __future__ import annotations

import re

import pytest

from atemr.robot.plain_words import ACTIONS, STATES, plain_outcome, plain_refusal

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
