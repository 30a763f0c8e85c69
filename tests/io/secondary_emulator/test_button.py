"""The power button: gestures by hold length, beeps per full second, input from other threads."""

from __future__ import annotations

import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from atemr.io.secondary_emulator.button import Button, Gesture, classify


@pytest.mark.parametrize(("held", "gesture"), [(0.0, Gesture.SHORT), (0.99, Gesture.SHORT), (1.0, Gesture.HOLD_1S),
                                               (4.99, Gesture.HOLD_1S), (5.0, Gesture.HOLD_5S),
                                               (12.0, Gesture.HOLD_5S)])
def test_classify(held: float, gesture: Gesture) -> None:
    assert classify(held) is gesture


def run(button: Button, until: float, dt: float = 0.02, start: float = 0.0) -> list:
    events = []
    steps = round((until - start) / dt)
    for k in range(steps + 1):
        events += button.poll(start + k * dt)
    return events


def test_hold_5s_beeps_five_times_then_completes() -> None:
    button = Button()
    button.hold(5.0)
    events = run(button, 6.0)
    beeps = [e for e in events if e.gesture is None]
    done = [e for e in events if e.gesture is not None]
    assert [e.seconds_held for e in beeps] == [1, 2, 3, 4, 5]
    assert [e.t for e in beeps] == pytest.approx([1, 2, 3, 4, 5])
    assert len(done) == 1 and done[0].gesture is Gesture.HOLD_5S and done[0].held_s == pytest.approx(5.0)
    assert not button.is_pressed


def test_press_and_release_timed_by_the_polls() -> None:
    button = Button()
    button.poll(10.0)
    button.press()
    button.poll(10.5)
    assert button.is_pressed and button.held_s(11.0) == pytest.approx(0.5)
    button.poll(11.2)
    button.release()
    events = button.poll(11.6)
    assert events[-1].gesture is Gesture.HOLD_1S and events[-1].held_s == pytest.approx(1.1)


def test_explicit_times() -> None:
    button = Button()
    button.press(at=2.0)
    button.release(at=2.4)
    events = button.poll(3.0)
    assert [e.gesture for e in events] == [Gesture.SHORT] and events[0].t == 2.4


def test_input_queued_behind_a_hold_waits_for_it() -> None:
    button = Button()
    button.hold(1.0)
    button.short_press()
    events = [e for e in run(button, 2.0) if e.gesture is not None]
    assert [e.gesture for e in events] == [Gesture.HOLD_1S, Gesture.SHORT]
    assert events[0].t == pytest.approx(1.0) and events[1].t == pytest.approx(1.0)


def test_release_without_press_and_double_press_are_harmless() -> None:
    button = Button()
    button.release()
    button.press()
    button.press()
    button.release()
    assert [e.gesture for e in button.poll(0.0)] == [Gesture.SHORT]


def test_negative_hold_refused() -> None:
    with pytest.raises(ValueError):
        Button().hold(-1.0)


def test_presses_from_other_threads() -> None:
    button = Button()
    threads = [threading.Thread(target=button.short_press) for _ in range(20)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    events = [e for e in run(button, 0.1) if e.gesture is not None]
    assert len(events) == 20


@given(st.floats(min_value=0.0, max_value=20.0), st.sampled_from([0.01, 0.02, 0.05]))
def test_hold_classified_by_its_length_at_any_tick_rate(seconds: float, dt: float) -> None:
    button = Button()
    button.hold(seconds)
    events = run(button, seconds + 2 * dt, dt=dt)
    done = [e for e in events if e.gesture is not None]
    assert len(done) == 1 and done[0].gesture is classify(seconds)
    assert sum(1 for e in events if e.gesture is None) == int(seconds + 1e-6)
