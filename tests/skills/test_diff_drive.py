import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.msgs import Pose2D, Twist, WheelSpeeds
from atemr.skills.diff_drive import DiffDrive, Odometry, arc_step, arc_step_one, wrap_angle

DRIVE = DiffDrive(0.085, 0.40, max_wheel_radps=math.inf)


def test_hand_computed_wheel_speeds():
    # 0.5 m/s straight: both wheels 0.5 / 0.085 rad/s
    left, right = DRIVE.wheel_speeds(0.5, 0.0)
    assert left == pytest.approx(5.882352941) and right == pytest.approx(5.882352941)
    # 1 rad/s on the spot: wheels ±0.2 m/s → ±2.3529 rad/s, left backwards
    left, right = DRIVE.wheel_speeds(0.0, 1.0)
    assert left == pytest.approx(-0.2 / 0.085) and right == pytest.approx(0.2 / 0.085)
    assert DRIVE.command(Twist(0.0, 1.0)) == WheelSpeeds(pytest.approx(-0.2 / 0.085), pytest.approx(0.2 / 0.085))


def test_wheel_limit_scales_both_wheels_and_keeps_curvature():
    drive = DiffDrive(max_wheel_radps=10.0)
    left, right = drive.wheel_speeds(1.6, 2.0)  # right wheel would need (1.6 + 0.4) / 0.085 = 23.5 rad/s
    assert max(abs(left), abs(right)) == pytest.approx(10.0)
    v, w = drive.twist(left, right)
    assert w / v == pytest.approx(2.0 / 1.6)


@settings(max_examples=50, deadline=None)
@given(st.floats(-3, 3), st.floats(-8, 8))
def test_command_agrees_with_the_vectorised_wheel_speeds(v, w):
    drive = DiffDrive()  # with the wheel limit
    left, right = drive.wheel_speeds(v, w)
    cmd = drive.command(Twist(v, w))
    assert cmd.left_radps == pytest.approx(float(left), abs=1e-12)
    assert cmd.right_radps == pytest.approx(float(right), abs=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.floats(-2, 2), st.floats(-4, 4))
def test_twist_wheel_round_trip(v, w):
    back = DRIVE.measured(DRIVE.command(Twist(v, w)))
    assert back.linear_mps == pytest.approx(v, abs=1e-12) and back.angular_radps == pytest.approx(w, abs=1e-12)


def test_arc_step_quarter_circle_and_straight_line():
    # v = 1 m/s, ω = π/2 rad/s for 1 s: a quarter circle of radius 2/π, ending at (2/π, 2/π) facing +y
    x, y, th = arc_step(0.0, 0.0, 0.0, 1.0, math.pi / 2, dt_s=1.0)
    assert (float(x), float(y), float(th)) == pytest.approx((2 / math.pi, 2 / math.pi, math.pi / 2))
    x, y, th = arc_step(1.0, 2.0, math.pi / 2, 0.5, 0.0, dt_s=2.0)
    assert (float(x), float(y), float(th)) == pytest.approx((1.0, 3.0, math.pi / 2))
    # vectorised over poses
    x, y, _ = arc_step(np.zeros(3), np.zeros(3), np.array([0.0, math.pi / 2, math.pi]), 1.0, 0.0, dt_s=1.0)
    np.testing.assert_allclose(x, [1, 0, -1], atol=1e-12)
    np.testing.assert_allclose(y, [0, 1, 0], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(v=st.floats(-1.5, 1.5), w=st.floats(-3, 3), dt=st.floats(0.01, 2.0), n=st.integers(1, 50))
def test_arc_steps_compose_exactly(v, w, dt, n):
    """n steps of dt/n land where one step of dt does: the integration has no discretisation error."""
    x = y = th = 0.0
    for _ in range(n):
        x, y, th = (float(a) for a in arc_step(x, y, th, v, w, dt_s=dt / n))
    one_step = tuple(float(a) for a in arc_step(0.0, 0.0, 0.0, v, w, dt_s=dt))
    assert (x, y, th) == pytest.approx(one_step, abs=1e-9)


def test_one_arc_step_in_floats_gives_the_arrays_bits():
    """The odometry filters step one pose in plain floats (`arc_step_one`); a seeded run must not depend on which
    path a step took, so both agree to the last bit: at ω = 0 (sinc's substitute), for tiny and large turns, and
    with infinities and NaN (which take the array path)."""
    rng = np.random.default_rng(4)
    n = 100_000
    x, y = rng.normal(0, 20, n), rng.normal(0, 20, n)
    yaw, v = rng.uniform(-7, 7, n), rng.normal(0, 1, n)
    w = np.where(rng.random(n) < 0.2, 0.0, rng.normal(0, 2, n) * 10.0 ** rng.integers(-12, 2, n))
    dt = rng.uniform(0, 0.05, n)
    w[:3], v[3], yaw[4], dt[5], w[6] = (-0.0, 1e-300, 5e-324), np.inf, np.nan, np.inf, np.inf
    with np.errstate(invalid="ignore"):
        batch = np.stack(arc_step(x, y, yaw, v, w, dt_s=dt), axis=1)
        for k in range(n):
            one = np.array(arc_step_one(float(x[k]), float(y[k]), float(yaw[k]), float(v[k]), float(w[k]),
                                        dt_s=float(dt[k])))
            assert one.tobytes() == batch[k].tobytes(), (k, one, batch[k])


def test_odometry_from_speeds_drives_a_full_circle():
    odo = Odometry(DRIVE)
    left, right = DRIVE.wheel_speeds(0.5, 0.5)  # radius 1 m, full circle in 4π s
    steps = 400
    for k in range(steps + 1):
        odo.update_speeds(k * 4 * math.pi / steps, WheelSpeeds(float(left), float(right)))
    assert odo.pose.x_m == pytest.approx(0.0, abs=1e-9) and odo.pose.y_m == pytest.approx(0.0, abs=1e-9)
    assert odo.distance_m == pytest.approx(2 * math.pi)
    assert odo.twist.linear_mps == pytest.approx(0.5)


def test_odometry_from_encoder_angles():
    odo = Odometry(DRIVE)
    odo.update_angles(0.0, 10.0, 10.0)
    # both wheels turn 1/0.085 rad: 1 m straight ahead in 2 s
    assert odo.update_angles(2.0, 10.0 + 1 / 0.085, 10.0 + 1 / 0.085)
    assert (odo.pose.x_m, odo.pose.y_m) == pytest.approx((1.0, 0.0))
    assert odo.twist.linear_mps == pytest.approx(0.5)
    # turn on the spot by π/2: wheel arc = π/2 · 0.2 m
    arc = math.pi / 2 * 0.2 / 0.085
    odo.update_angles(3.0, 10.0 + 1 / 0.085 - arc, 10.0 + 1 / 0.085 + arc)
    assert odo.pose.yaw_rad == pytest.approx(math.pi / 2)
    assert odo.pose.x_m == pytest.approx(1.0)


def test_odometry_ignores_bad_feedback():
    odo = Odometry(DRIVE, pose=Pose2D(1.0, 1.0, 0.0))
    odo.update_speeds(0.0, WheelSpeeds(1.0, 1.0))
    assert not odo.update_speeds(0.1, WheelSpeeds(math.nan, 1.0))
    assert not odo.update_speeds(-1.0, WheelSpeeds(1.0, 1.0))
    assert not odo.update_angles(0.2, math.inf, 0.0)
    assert odo.rejected == 3 and odo.pose == Pose2D(1.0, 1.0, 0.0)
    odo.reset()
    assert odo.pose == Pose2D()


def test_wrap_and_bad_geometry():
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    with pytest.raises(ConfigError, match="track_m"):
        DiffDrive(track_m=0.0)
    with pytest.raises(ConfigError, match="wheel_radius_m"):
        DiffDrive(wheel_radius_m=math.nan)
