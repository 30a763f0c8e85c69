import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.msgs import Twist
from atemr.skills.ramp import Clearance, IdleDetector, MotionLimits, SpeedRamp, checked_limits

CLEAR = Clearance()
DT = 0.02


def run(ramp, target, seconds, clearance=CLEAR, t0=0.0, command=None):
    out = None
    n = round(seconds / DT)
    for k in range(n + 1):
        out = ramp.step(t0 + k * DT, target, clearance, command=command)
    return out


def test_linear_ramp_in_time_with_separate_limits():
    ramp = SpeedRamp({"linear_accel_mps2": 0.5, "angular_accel_radps2": 2.0})
    out = run(ramp, Twist(1.0, 1.0), 0.4)
    # 0.4 s at 0.5 m/s² → 0.2 m/s; at 2 rad/s² → 0.8 rad/s
    assert out.twist.linear_mps == pytest.approx(0.2) and out.twist.angular_radps == pytest.approx(0.8)
    out = run(ramp, Twist(1.0, 1.0), 2.0, t0=0.42)
    assert out.twist == Twist(1.0, 1.0)  # reached exactly, no overshoot
    out = run(ramp, Twist(0.0, 0.0), 0.5, t0=2.44)
    assert out.twist.linear_mps == pytest.approx(0.74) and out.twist.angular_radps == pytest.approx(0.0)


def test_target_is_clamped_to_the_limits():
    ramp = SpeedRamp({"max_linear_mps": 1.0, "max_angular_radps": 1.5})
    out = run(ramp, Twist(5.0, -9.0), 10.0)
    assert out.twist == Twist(1.0, -1.5)


def test_slow_zone_limits_speed_in_the_direction_of_travel():
    ramp = SpeedRamp()
    out = run(ramp, Twist(1.0, 3.0), 5.0, Clearance(front_m=0.5, rear_m=math.inf))
    assert out.slow and not out.emergency
    assert out.twist == Twist(0.35, 1.6)
    # an obstacle behind a base that drives forward does not slow it
    ramp = SpeedRamp()
    out = run(ramp, Twist(1.0, 0.0), 5.0, Clearance(front_m=math.inf, rear_m=0.4))
    assert not out.slow and out.twist.linear_mps == pytest.approx(1.0)
    # turning on the spot is slowed by anything near
    out = run(SpeedRamp(), Twist(0.0, 2.0), 5.0, Clearance(front_m=math.inf, rear_m=0.4))
    assert out.slow and out.twist.angular_radps == pytest.approx(1.6)


def test_stop_zone_is_an_emergency_that_bypasses_the_ramp_and_resumes_2s_after_clear():
    ramp = SpeedRamp()
    run(ramp, Twist(0.3, 0.0), 2.0, Clearance(front_m=0.5))
    assert ramp.velocity.linear_mps == pytest.approx(0.3)
    out = ramp.step(2.02, Twist(0.3, 0.0), Clearance(front_m=0.27))
    assert out.emergency and out.twist.is_zero and ramp.velocity.is_zero  # at once, no ramp down
    out = ramp.step(3.0, Twist(0.3, 0.0), Clearance(front_m=0.27))
    assert out.emergency
    # obstacle gone at t=3.02: still stopped until t=5.02
    out = ramp.step(3.02, Twist(0.3, 0.0), Clearance(front_m=0.8))
    assert out.emergency
    out = ramp.step(5.0, Twist(0.3, 0.0), Clearance(front_m=0.8))
    assert out.emergency
    out = ramp.step(5.02, Twist(0.3, 0.0), Clearance(front_m=0.8))
    assert not out.emergency and out.twist.linear_mps == pytest.approx(0.02)  # ramps up from zero


def test_obstacle_returning_restarts_the_resume_delay():
    ramp = SpeedRamp()
    ramp.step(0.0, Twist(0.3, 0.0), Clearance(front_m=0.2))
    ramp.step(1.0, Twist(0.3, 0.0), Clearance(front_m=0.5))
    ramp.step(2.0, Twist(0.3, 0.0), Clearance(front_m=0.2))
    assert ramp.step(3.5, Twist(0.3, 0.0), Clearance(front_m=0.5)).emergency
    assert ramp.step(5.4, Twist(0.3, 0.0), Clearance(front_m=0.5)).emergency
    assert not ramp.step(5.5, Twist(0.3, 0.0), Clearance(front_m=0.5)).emergency


def test_backing_away_from_the_wall_is_possible_after_the_resume_delay():
    ramp = SpeedRamp()
    wall = Clearance(front_m=0.25)
    assert ramp.step(0.0, Twist(0.2, 0.0), wall).emergency
    assert ramp.step(1.0, Twist(-0.2, 0.0), wall).emergency
    assert ramp.step(2.98, Twist(-0.2, 0.0), wall).emergency
    out = ramp.step(3.0, Twist(-0.2, 0.0), wall)
    assert not out.emergency and out.slow is False
    assert out.twist.linear_mps == pytest.approx(-0.02)
    # pushing forward again stops at once
    assert ramp.step(3.2, Twist(0.2, 0.0), wall).emergency


def test_blind_base_moves_only_at_slow_limits():
    out = run(SpeedRamp(), Twist(1.0, 0.0), 3.0, clearance=None)
    assert out.slow and not out.emergency and out.twist.linear_mps == pytest.approx(0.35)


def test_idle_after_8s_without_state_changing_command():
    ramp = SpeedRamp()
    out = run(ramp, Twist(), 7.9, command=Twist())
    assert not out.idle
    assert ramp.step(8.0, Twist(), CLEAR, command=Twist()).idle  # zeros streaming do not change state
    assert not ramp.step(8.02, Twist(0.1, 0.0), CLEAR, command=Twist(0.1, 0.0)).idle
    assert not ramp.step(16.0, Twist(), CLEAR, command=Twist()).idle  # a stop is a change: 8 s from here
    assert ramp.step(24.0, Twist(), CLEAR, command=None).idle


def test_idle_detector_wake():
    d = IdleDetector()
    assert not d.observe(0.0, None, 8.0)
    assert d.observe(8.0, None, 8.0)
    d.wake(8.5)
    assert not d.observe(9.0, None, 8.0)


def test_non_finite_target_means_stop():
    ramp = SpeedRamp()
    run(ramp, Twist(0.5, 0.0), 1.0)
    out = ramp.step(1.04, Twist(math.nan, 0.0), CLEAR)
    assert out.twist.linear_mps == pytest.approx(0.46)


def test_set_limits_validates_and_keeps_the_old_on_rejection():
    ramp = SpeedRamp()
    assert ramp.set_limits({"max_linear_mps": "1.2"}).max_linear_mps == 1.2
    before = ramp.limits
    for bad, match in [
        ({"max_linear_mps": 2.5}, "max_linear_mps: must be at most 1.8"),
        ({"max_linear_mps": 1.0, "stop_distance_m": 0.9}, "must not exceed slow_distance_m"),
        ({"max_linear_mps": math.nan}, "finite"),
        ({"speed": 1.0}, "unknown key 'speed'"),
    ]:
        with pytest.raises(ConfigError, match=match):
            ramp.set_limits(bad)
        assert ramp.limits is before
    # a whole MotionLimits object is checked field by field too
    with pytest.raises(ConfigError, match=r"at least 0\.05"):
        ramp.set_limits(MotionLimits(linear_accel_mps2=0.0))
    with pytest.raises(ConfigError):
        SpeedRamp({"idle_after_s": -1})
    assert checked_limits({}) == MotionLimits()


def test_lowered_limit_brings_speed_down_at_the_ramp_rate():
    ramp = SpeedRamp()
    run(ramp, Twist(1.5, 0.0), 3.0)
    ramp.set_limits({"max_linear_mps": 0.5})
    out = ramp.step(3.1, Twist(1.5, 0.0), CLEAR)
    assert out.twist.linear_mps == pytest.approx(1.4)


# ---- property test: whatever the inputs, the ramp's limits hold -------------------------------------

step_st = st.tuples(
    st.floats(0.0, 0.2),  # dt
    st.floats(-3, 3),  # target v
    st.floats(-5, 5),  # target w
    st.floats(0.0, 2.0),  # front clearance
    st.floats(0.0, 2.0),  # rear clearance
)


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(step_st, min_size=1, max_size=80),
    accel=st.floats(0.1, 3.0),
    alpha=st.floats(0.1, 10.0),
    vmax=st.floats(0.0, 1.8),
)
def test_property_accel_speed_and_zone_limits(steps, accel, alpha, vmax):
    lim = checked_limits({"linear_accel_mps2": accel, "angular_accel_radps2": alpha, "max_linear_mps": vmax})
    ramp = SpeedRamp(lim)
    t, prev = 0.0, Twist()
    for dt, tv, tw, front, rear in steps:
        t += dt
        out = ramp.step(t, Twist(tv, tw), Clearance(front, rear))
        v, w = out.twist.linear_mps, out.twist.angular_radps
        if out.emergency:
            assert out.twist.is_zero
        else:
            first = t == steps[0][0]
            assert abs(v - prev.linear_mps) <= accel * (0.0 if first else dt) + 1e-9
            assert abs(w - prev.angular_radps) <= alpha * (0.0 if first else dt) + 1e-9
            cap = lim.slow_linear_mps if out.slow else lim.max_linear_mps
            assert abs(v) <= max(abs(prev.linear_mps), min(cap, lim.max_linear_mps)) + 1e-9
            # never moving towards something inside the stop zone, nor towards one the base could not stop short of
            if v > 0:
                assert front >= lim.stop_distance_m
                assert front - max(prev.linear_mps, 0.0) * lim.brake_latency_s >= lim.stop_distance_m
            if v < 0:
                assert rear >= lim.stop_distance_m
                assert rear - max(-prev.linear_mps, 0.0) * lim.brake_latency_s >= lim.stop_distance_m
        prev = out.twist


# ---- the stop zone anticipates the braking distance (motor lag + one control period) ---------------------


def cruising(v=0.3, **limits):
    """A ramp that has been driving steadily at ``v`` (m/s) in the open for 2 s."""
    ramp = SpeedRamp(limits)
    run(ramp, Twist(v, 0.0), 2.0)
    assert ramp.velocity.linear_mps == pytest.approx(v)
    return ramp


def test_braking_distance_is_speed_times_brake_latency_in_the_direction_of_travel():
    assert MotionLimits().brake_latency_s == 0.12
    ramp = cruising(0.3)
    assert ramp.braking_distance_m(1) == pytest.approx(0.036)
    assert ramp.braking_distance_m(-1) == 0.0
    ramp = cruising(-0.2)
    assert ramp.braking_distance_m(-1) == pytest.approx(0.024)
    assert ramp.braking_distance_m(1) == 0.0
    assert SpeedRamp().braking_distance_m(1) == 0.0  # at rest


def test_the_stop_zone_triggers_where_the_base_would_come_to_rest():
    # 0.3 m/s covers 3.6 cm before it can stop: 0.305 m now is 0.269 m at rest, inside the 0.28 m stop zone
    ramp = cruising(0.3)
    out = ramp.step(2.04, Twist(0.3, 0.0), Clearance(front_m=0.305))
    assert out.emergency and out.twist.is_zero and ramp.velocity.is_zero
    assert out.guard_m == pytest.approx(0.305)  # the telemetry shows the clearance itself
    # 0.32 m now is 0.284 m at rest: slow zone, no emergency
    ramp = cruising(0.3)
    out = ramp.step(2.04, Twist(0.3, 0.0), Clearance(front_m=0.32))
    assert not out.emergency and out.slow and out.twist.linear_mps == pytest.approx(0.3)


def test_the_anticipation_grows_with_speed_and_watches_the_direction_of_travel():
    ramp = cruising(1.0)  # 12 cm before it can stop
    assert ramp.step(2.04, Twist(1.0, 0.0), Clearance(front_m=0.39)).emergency
    # reversing: the rear clearance is anticipated, the front one is not
    ramp = cruising(-0.3)
    assert not ramp.step(2.04, Twist(-0.3, 0.0), Clearance(front_m=0.29, rear_m=0.32)).emergency
    ramp = cruising(-0.3)
    assert ramp.step(2.04, Twist(-0.3, 0.0), Clearance(front_m=math.inf, rear_m=0.305)).emergency


def test_a_base_at_rest_may_start_next_to_the_stop_zone():
    ramp = SpeedRamp()
    out = ramp.step(0.0, Twist(0.3, 0.0), Clearance(front_m=0.285))
    assert not out.emergency
    out = ramp.step(0.02, Twist(0.3, 0.0), Clearance(front_m=0.285))
    assert not out.emergency and out.twist.linear_mps == pytest.approx(0.02)


def test_zero_brake_latency_is_the_plain_stop_distance():
    ramp = cruising(0.3, brake_latency_s=0.0)
    assert not ramp.step(2.04, Twist(0.3, 0.0), Clearance(front_m=0.285)).emergency
    assert ramp.step(2.06, Twist(0.3, 0.0), Clearance(front_m=0.279)).emergency


def test_an_early_stop_holds_until_the_obstacle_is_beyond_the_braking_distance():
    # stopped early at 0.30 m (outside the 0.28 m zone): the base must not creep on towards the obstacle every 2 s
    ramp = cruising(0.3)
    near = Clearance(front_m=0.30)
    assert ramp.step(2.04, Twist(0.3, 0.0), near).emergency
    for k in range(1, 300):  # 6 s with the operator still pushing forward
        assert ramp.step(2.04 + k * DT, Twist(0.3, 0.0), near).emergency
    # the obstacle moves beyond 0.28 + 0.036 m: resume 2 s later, then the zone is the plain one again
    t = 2.04 + 300 * DT
    away = Clearance(front_m=0.32)
    assert ramp.step(t, Twist(0.3, 0.0), away).emergency
    assert ramp.step(t + 1.98, Twist(0.3, 0.0), away).emergency
    out = ramp.step(t + 2.0, Twist(0.3, 0.0), away)
    assert not out.emergency and out.twist.linear_mps == pytest.approx(0.02)


def test_brake_latency_is_a_checked_run_time_limit():
    ramp = SpeedRamp()
    assert ramp.set_limits({"brake_latency_s": "0.2"}).brake_latency_s == 0.2
    for bad in ({"brake_latency_s": -0.1}, {"brake_latency_s": 1.5}, {"brake_latency_s": math.inf}):
        with pytest.raises(ConfigError, match="brake_latency_s"):
            ramp.set_limits(bad)
        assert ramp.limits.brake_latency_s == 0.2


# ---- the slow zone is anticipated by the deceleration distance ------------------------------------------------


def test_towards_an_obstacle_the_target_is_capped_so_the_base_is_slow_at_the_slow_zone_edge():
    # cruising at 0.5 m/s, 0.65 m from a wall: 0.06 m go by before a command acts (0.5 × 0.12 s), 0.03 m remain
    # to the slow zone's edge, and from v the base stops decelerating at 1 m/s² exactly at 0.35 m/s when
    # v² = 0.35² + 2 × 1 × 0.03 → v = 0.4272 m/s: the target is cut to that, the ramp heads there at once
    ramp = cruising(0.5)
    out = ramp.step(2.04, Twist(0.5, 0.0), Clearance(front_m=0.65))
    assert not out.slow and not out.emergency  # not in the slow zone yet: the flag is the zone's, not the envelope's
    assert out.twist.linear_mps == pytest.approx(0.5 - 0.04)  # 40 ms at the ramp's rate, on the way to 0.4272
    # held there, it settles where the cap at its own speed is its speed: v² + 0.24 v − 0.3025 = 0 → 0.44294 m/s
    ramp = cruising(0.5)
    run(ramp, Twist(0.5, 0.0), 2.0, Clearance(front_m=0.65), t0=2.04)
    assert ramp.velocity.linear_mps == pytest.approx((-0.24 + math.sqrt(0.24**2 + 4 * 0.3025)) / 2, abs=1e-6)
    # far from anything the cap is above the speed asked for, and driving away from a near obstacle is not capped
    assert cruising(0.5).step(2.04, Twist(0.5, 0.0), Clearance(front_m=1.2)).twist.linear_mps == pytest.approx(0.5)
    assert cruising(0.5).step(2.04, Twist(0.5, 0.0), Clearance(rear_m=0.6)).twist.linear_mps == pytest.approx(0.5)


@settings(max_examples=60, deadline=None)
@given(v=st.floats(0.36, 1.6), accel=st.floats(0.2, 3.0), room=st.floats(0.0, 2.0))
def test_property_driving_at_a_wall_the_base_enters_the_slow_zone_at_slow_speed(v, accel, room):
    lim = checked_limits({"linear_accel_mps2": accel})
    # starting where it still can: the zone edge plus the latency travel plus the deceleration distance, plus room
    start = lim.slow_distance_m + v * lim.brake_latency_s + (v**2 - lim.slow_linear_mps**2) / (2 * accel) + room
    ramp = SpeedRamp(lim)
    run(ramp, Twist(v, 0.0), v / accel + 0.1)  # cruising at v in the open
    gap, t = start, v / accel + 0.1
    while gap >= lim.slow_distance_m:
        t += DT
        out = ramp.step(t, Twist(v, 0.0), Clearance(front_m=gap))
        # the ramp's command acts after brake_latency_s: where the base is then must be slow enough
        gap -= out.twist.linear_mps * DT
    assert out.twist.linear_mps <= lim.slow_linear_mps + accel * DT + 1e-9
