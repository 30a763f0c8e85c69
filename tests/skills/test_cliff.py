import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.msgs import CliffReadings, Twist
from atemr.skills.cliff import CliffGeometry, CliffStop, blocked, drops

FLOOR = 0.06
G = CliffGeometry()


def readings(fl=FLOOR, fr=FLOOR, rear=FLOOR, t=0.0):
    return CliffReadings(t, fl, fr, rear)


def test_drop_detection_threshold_and_faults():
    assert drops(readings(), G).tolist() == [False, False, False]
    assert drops(readings(fl=0.11, fr=0.099, rear=math.inf), G).tolist() == [True, False, True]
    assert drops(readings(fr=math.nan), G).tolist() == [False, True, False]


@pytest.mark.parametrize(
    ("dropped", "v", "w", "expect"),
    [
        ((True, False, False), 0.3, 0.0, True),  # forward towards a front-left drop
        ((True, False, False), -0.3, 0.0, False),  # backing away
        ((True, False, False), 0.0, 1.0, False),  # turning left swings the front-left sensor back
        ((True, False, False), 0.0, -1.0, True),  # turning right swings it forward
        ((False, True, False), 0.0, 1.0, True),  # turning left swings front-right forward
        ((False, False, True), -0.2, 0.0, True),  # reversing towards a rear drop
        ((False, False, True), 0.2, 0.5, False),
        ((False, False, False), 1.0, 1.0, False),
    ],
)
def test_blocks_only_motion_towards_the_drop(dropped, v, w, expect):
    assert bool(blocked(v, w, dropped, G)) is expect


def test_blocked_is_vectorised_over_twists():
    v = np.array([0.3, -0.3, 0.0, 0.0])
    w = np.array([0.0, 0.0, 1.0, -1.0])
    assert blocked(v, w, (True, False, False), G).tolist() == [True, False, False, True]


def test_cliff_stop_vetoes_at_once_and_passes_safe_twists():
    stop = CliffStop()
    verdict = stop.check(0.1, Twist(0.3, 0.0), readings(fl=math.inf))
    assert verdict.stopped and verdict.twist.is_zero and verdict.drops == (True, False, False)
    verdict = stop.check(0.1, Twist(-0.3, 0.0), readings(fl=math.inf))
    assert not verdict.stopped and verdict.twist == Twist(-0.3, 0.0)


def test_missing_or_stale_readings():
    safe = CliffStop(max_age_s=0.5)
    assert safe.check(1.0, Twist(0.2, 0.0), None).stopped
    assert safe.check(1.0, Twist(-0.2, 0.0), readings(t=0.4)).stopped  # 0.6 s old: every sensor a drop
    assert not safe.check(1.0, Twist(0.2, 0.0), readings(t=0.6)).stopped
    lenient = CliffStop(require_readings=False)
    assert not lenient.check(1.0, Twist(0.2, 0.3), None).stopped


def test_a_stop_for_want_of_readings_is_told_apart_from_a_drop_seen():
    """The dashboard tells a carer "the floor sensors went quiet", not "stairs under the robot", when it is so."""
    safe = CliffStop(max_age_s=0.5)
    assert safe.check(1.0, Twist(0.2, 0.0), None).blind
    assert safe.check(1.0, Twist(0.2, 0.0), readings(t=0.4)).blind
    seen = safe.check(1.0, Twist(0.2, 0.0), readings(fl=math.inf, t=0.9))
    assert seen.stopped and not seen.blind
    assert not CliffStop(require_readings=False).check(1.0, Twist(0.2, 0.0), None).blind


def test_bad_geometry():
    with pytest.raises(ConfigError, match="floor_distance_m"):
        CliffGeometry(floor_distance_m=0.0)
    with pytest.raises(ConfigError, match="ahead of the axle"):
        CliffGeometry(rear_xy=(0.1, 0.0))
    with pytest.raises(ConfigError, match="max_age_s"):
        CliffStop(max_age_s=math.inf)


@settings(max_examples=80, deadline=None)
@given(v=st.floats(-2, 2), w=st.floats(-4, 4),
       readings_m=st.tuples(*[st.sampled_from([0.05, 0.06, 0.11, math.inf, math.nan])] * 3))
def test_the_per_tick_check_agrees_with_the_vectorised_rule(v, w, readings_m):
    verdict = CliffStop().check(0.0, Twist(v, w), CliffReadings(0.0, *readings_m))
    dropped = drops(CliffReadings(0.0, *readings_m), G)
    assert verdict.drops == tuple(bool(d) for d in dropped)
    assert verdict.stopped == bool(blocked(v, w, dropped, G))
