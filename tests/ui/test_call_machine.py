"""The call's signalling state machine, pure: who rings, who answers, who hangs up, where signals go."""

from __future__ import annotations

import pytest

from atemr.ui.call.machine import SIGNAL_EVENT, STATE_EVENT, CallMachine, Send


def states(outcome) -> dict[str, tuple[str, str]]:
    """sid → (state, reason) of every call_state message."""
    return {s.to: (s.data["state"], s.data["reason"]) for s in outcome.sends if s.event == STATE_EVENT}


def test_ring_answer_signal_hang_up():
    m = CallMachine()
    ring = m.ring("op", "alice", ["scr"])
    assert ring.ok and states(ring) == {"op": ("ringing", ""), "scr": ("ringing", "")}
    assert all(s.data["caller"] == "alice" for s in ring.sends)
    answer = m.answer("scr")
    assert answer.ok and states(answer) == {"op": ("active", ""), "scr": ("active", "")}
    offer = {"description": {"type": "offer", "sdp": "v=0"}}
    assert m.relay("op", offer).sends == (Send("scr", SIGNAL_EVENT, offer),)
    assert m.relay("scr", {"candidate": None}).sends == (Send("op", SIGNAL_EVENT, {"candidate": None}),)
    end = m.hang_up("scr")
    assert end.ok and states(end) == {"scr": ("idle", "you hung up"), "op": ("idle", "the robot's screen hung up")}
    assert m.phase == "idle" and m.operator is None


def test_one_call_at_a_time_with_the_reason():
    m = CallMachine()
    m.ring("op1", "alice", ["scr"])
    refused = m.ring("op2", "carol", ["scr"])
    assert not refused.ok and refused.sends == ()
    assert refused.reason == "the robot is ringing with alice: one call at a time"
    m.answer("scr")
    assert m.ring("op2", "carol", ["scr"]).reason == "the robot is in a call with alice: one call at a time"
    assert m.ring("op1", "alice", ["scr"]).reason == "the robot is in a call with you: one call at a time"
    assert m.operator == "op1" and m.phase == "active"


def test_no_screen_no_call():
    m = CallMachine()
    out = m.ring("op", "alice", [])
    assert not out.ok and "screen is not connected" in out.reason and m.phase == "idle"


def test_auto_answer_goes_active_at_once():
    m = CallMachine()
    out = m.ring("op", "alice", ["scr1", "scr2"], auto_answer=True)
    assert states(out) == {"op": ("active", ""), "scr1": ("active", ""), "scr2": ("idle", "answered on another screen")}
    assert m.screen == "scr1"


def test_decline_tells_the_caller():
    m = CallMachine()
    m.ring("op", "alice", ["scr"])
    out = m.decline("scr")
    assert states(out) == {"op": ("idle", "the robot's screen declined the call"),
                           "scr": ("idle", "you declined the call")}
    assert m.phase == "idle"


def test_operator_hangs_up_while_ringing_every_rung_screen_stops():
    m = CallMachine()
    m.ring("op", "alice", ["a", "b"])
    assert states(m.hang_up("op")) == {"op": ("idle", "you hung up"), "a": ("idle", "the caller hung up"),
                                      "b": ("idle", "the caller hung up")}


@pytest.mark.parametrize(("gone", "told", "reason"), [("op", "scr", "the caller left"),
                                                       ("scr", "op", "the robot's screen left")])
def test_a_party_leaving_ends_the_call(gone, told, reason):
    m = CallMachine()
    m.ring("op", "alice", ["scr"])
    m.answer("scr")
    out = m.left(gone)
    assert states(out)[told] == ("idle", reason) and m.phase == "idle"


def test_a_bystander_leaving_changes_nothing():
    m = CallMachine()
    m.ring("op", "alice", ["scr"])
    m.answer("scr")
    assert m.left("someone-else").sends == () and m.phase == "active"


def test_one_of_two_ringing_screens_leaving_keeps_ringing_the_last_ends_it():
    m = CallMachine()
    m.ring("op", "alice", ["a", "b"])
    assert m.left("a").sends == () and m.phase == "ringing"
    assert states(m.left("b"))["op"] == ("idle", "the robot's screen left")


@pytest.mark.parametrize("who", ["op", "scr", "other"])
def test_signals_only_between_the_parties_of_an_active_call(who):
    m = CallMachine()
    assert not m.relay(who, {"candidate": None}).ok  # idle
    m.ring("op", "alice", ["scr"])
    assert not m.relay(who, {"candidate": None}).ok  # ringing: no offer before the answer
    m.answer("scr")
    assert m.relay(who, {"candidate": None}).ok is (who != "other")


def test_answers_and_hang_ups_from_strangers_are_refused():
    m = CallMachine()
    assert m.answer("scr").reason == "there is no call ringing on this screen"
    assert m.hang_up("op").reason == "there is no call to end"
    m.ring("op", "alice", ["scr"])
    assert not m.answer("intruder").ok and not m.decline("intruder").ok and not m.hang_up("intruder").ok
    assert m.phase == "ringing"
