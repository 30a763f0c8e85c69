"""The odometry EKF learns the gyro's bias while the wheels stand still and takes it out of every reading: a robot
standing does not turn in ``odom``, and a robot that stood once drives straighter after."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atemr.io.sim.imu import Imu, ImuParams
from atemr.msgs import Twist, WheelSpeeds
from atemr.skills.diff_drive import DiffDrive
from atemr.skills.localization.odometry_ekf import OdometryEkf

#: 1.5 σ of the simulated IMU's turn-on bias (rad/s): 0.18 rad a minute when left in.
BIAS = 0.003


def gyro(seed: int = 3) -> Imu:
    imu = Imu(ImuParams(), np.random.default_rng(seed))
    imu.gyro_bias_radps = BIAS
    return imu


def run(ekf: OdometryEkf, imu: Imu, start: float, end: float, v: float = 0.0, w: float = 0.0, *,
        wheels_w: float | None = None) -> float:
    """Wheels at 100 Hz (reading ``wheels_w`` for the turn, or the true ``w``), the gyro at 50 Hz, from ``start``
    to ``end`` (s); the robot's true heading change over it is returned."""
    k = round(start * 100)
    while k < round(end * 100):
        k += 1
        t = k / 100
        ekf.update_wheels(t, Twist(v, w if wheels_w is None else wheels_w))
        if k % 2 == 0:
            ekf.update_imu(imu.sample(t, v, w, 0.0))
    return w * (end - start)


def test_a_standing_robot_learns_the_bias_within_seconds_and_does_not_turn() -> None:
    ekf, imu = OdometryEkf(), gyro()
    run(ekf, imu, 0.0, 2.0)
    assert ekf.standing
    assert abs(ekf.gyro_bias_radps - BIAS) < 0.001, ekf.gyro_bias_radps
    run(ekf, imu, 2.0, 300.0)
    assert abs(ekf.gyro_bias_radps - BIAS) < 0.0005, ekf.gyro_bias_radps
    # the bias alone would have turned it by 0.9 rad in five minutes
    assert abs(ekf.pose.yaw_rad) < math.radians(0.5), ekf.pose


def test_a_robot_that_stood_drives_straighter_than_one_that_never_did() -> None:
    """The bias learned while standing stays out while driving: a 40 s straight line keeps its heading. Without it,
    the fusion follows the gyro more than the wheels and turns by most of its bias."""
    stood, imu = OdometryEkf(), gyro()
    run(stood, imu, 0.0, 20.0)
    heading = stood.pose.yaw_rad
    run(stood, imu, 20.0, 60.0, v=0.4)
    fresh = OdometryEkf()
    run(fresh, gyro(), 0.0, 40.0, v=0.4)
    assert fresh.gyro_bias_radps == 0.0  # it never stood, so it never learned
    assert abs(stood.pose.yaw_rad - heading) < 0.02, stood.pose  # the gyro's noise, and the estimate's
    assert abs(fresh.pose.yaw_rad) > 0.05, fresh.pose  # the bias: 0.12 rad over 40 s, two thirds of it fused


def test_turning_wheels_teach_nothing() -> None:
    """A robot turning on its wheels: the gyro reads the turn, not the bias."""
    ekf, imu = OdometryEkf(), gyro()
    turned = run(ekf, imu, 0.0, 10.0, 0.0, 0.3)
    assert ekf.gyro_bias_radps == 0.0 and not ekf.standing
    assert abs(ekf.pose.yaw_rad - turned) < 0.1


def test_a_robot_turned_by_hand_with_its_wheels_still_is_fused_not_learned() -> None:
    """Lifted and turned at half a radian a second, its wheels reading zero: the gyro's rate is a turn, far from
    the bias learned, so it moves the odometry (against the wheels' zero, which holds back about a third of it) and
    leaves the bias alone."""
    ekf, imu = OdometryEkf(), gyro()
    run(ekf, imu, 0.0, 5.0)
    learned, before = ekf.gyro_bias_radps, ekf.pose.yaw_rad
    turned = run(ekf, imu, 5.0, 7.0, 0.0, 0.5, wheels_w=0.0)
    assert ekf.gyro_bias_radps == learned
    assert 0.5 * turned < ekf.pose.yaw_rad - before <= turned


def test_the_bias_follows_a_drift_with_its_time_constant() -> None:
    """A gyro warming up: its bias moves by 0.004 rad/s. Within three time constants the estimate has followed."""
    ekf, imu = OdometryEkf(), gyro()
    run(ekf, imu, 0.0, 60.0)
    imu.gyro_bias_radps = BIAS + 0.004
    run(ekf, imu, 60.0, 60.0 + 3 * ekf.params.gyro_bias_tau_s)
    assert abs(ekf.gyro_bias_radps - (BIAS + 0.004)) < 0.0005, ekf.gyro_bias_radps


def test_motors_reading_a_step_either_way_still_stand() -> None:
    """A standing motor may report one step of its speed resolution (1°/s) either way: the robot still stands, so
    the bias is learned and the pipeline skips ICP. Two steps on a wheel is motion."""
    drive, step = DiffDrive(), math.radians(1.0)
    ekf, imu = OdometryEkf(), gyro()
    jitter = np.random.default_rng(5).integers(-1, 2, (500, 2)) * step
    for k, (left, right) in enumerate(jitter, start=1):
        ekf.update_wheels(k / 100, drive.measured(WheelSpeeds(float(left), float(right))))
        if k % 2 == 0:
            ekf.update_imu(imu.sample(k / 100, 0.0, 0.0, 0.0))
    assert ekf.standing and abs(ekf.gyro_bias_radps - BIAS) < 0.001, ekf.gyro_bias_radps
    assert not ekf.stands_still(drive.measured(WheelSpeeds(2 * step, 2 * step)))
    assert not ekf.stands_still(drive.measured(WheelSpeeds(-2 * step, 2 * step)))


def test_silent_wheels_do_not_say_the_robot_stands() -> None:
    """The motors stop answering (a bus gone off) while the robot stood: from then on the gyro teaches nothing, so a
    robot pushed round slowly by hand meanwhile keeps its turn in the odometry instead of learning it as a bias."""
    ekf, imu = OdometryEkf(), gyro()
    run(ekf, imu, 0.0, 5.0)
    learned, before = ekf.gyro_bias_radps, ekf.pose.yaw_rad
    for k in range(501, 1501):  # ten seconds turning at 0.02 rad/s (inside the gate), with no wheel reading
        if k % 2 == 0:
            ekf.update_imu(imu.sample(k / 100, 0.0, 0.02, 0.0))
    assert not ekf.standing
    # the first 0.2 s of silence still count as standing (WHEELS_SILENT_S): ten readings, a few hundredths of the turn
    assert abs(ekf.gyro_bias_radps - learned) < 0.001, (ekf.gyro_bias_radps, learned)
    assert ekf.pose.yaw_rad - before == pytest.approx(0.2, abs=0.03)
