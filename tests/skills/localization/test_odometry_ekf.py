"""EKF consistency (NEES within χ² bounds on a seeded run of the filter's own model) and fusion in the simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from scipy import stats

from atemr.errors import ConfigError, NavigationError
from atemr.msgs import ImuSample, Pose2D, Twist
from atemr.skills.diff_drive import arc_step, wrap_angle
from atemr.skills.localization.amcl import PoseEstimate
from atemr.skills.localization.geometry import as_array, as_pose, compose, relative
from atemr.skills.localization.icp import icp
from atemr.skills.localization.odometry_ekf import MapEkf, OdometryEkf, OdometryEkfParams, kalman_update
from atemr.skills.localization.scan import scan_points


def nees(err: np.ndarray, cov: np.ndarray) -> float:
    return float(err @ np.linalg.solve(cov, err))


def mean_nees(truth: OdometryEkfParams, filt: OdometryEkfParams, *, runs: int = 12, steps: int = 300) -> float:
    """Average 5-state NEES over time and seeded Monte Carlo runs, truth drawn from the model ``truth``."""
    p = truth
    rng = np.random.default_rng(42)
    dt = 0.02
    values = []
    for _ in range(runs):
        ekf = OdometryEkf(filt)
        x = np.array([0.0, 0.0, 0.0, 0.3, 0.2])
        ekf.kf.x = x.copy()
        ekf.kf.P = np.diag([1e-9, 1e-9, 1e-9, 0.01, 0.01])
        x[3:] += rng.normal(0.0, 0.1, 2)  # the filter starts uncertain about the twist
        q = np.array([p.pose_std_per_rts, p.pose_std_per_rts, p.yaw_std_per_rts, p.accel_std_per_rts,
                      p.angular_accel_std_per_rts]) * math.sqrt(dt)
        for k in range(1, steps + 1):
            t = k * dt
            nx, ny, nth = arc_step(x[0], x[1], x[2], x[3], x[4], dt_s=dt)
            x = np.array([float(nx), float(ny), float(nth), x[3], x[4]]) + rng.normal(0.0, 1.0, 5) * q
            wheels = Twist(x[3] + rng.normal(0, p.wheel_v_std_mps), x[4] + rng.normal(0, p.wheel_w_std_radps))
            ekf.update_wheels(t, wheels)
            ekf.update_imu(ImuSample(t, x[4] + rng.normal(0, p.gyro_std_radps), 0.0, 0.0))
            if k > 50:
                e = x - ekf.state
                e[2] = wrap_angle(e[2])
                values.append(nees(e, ekf.covariance))
    return float(np.mean(values))


def test_odometry_ekf_nees_is_consistent() -> None:
    """Monte Carlo NEES (Bar-Shalom, Estimation with Applications to Tracking and Navigation, §5.4): with the
    truth drawn from the filter's own model, the average NEES lies inside the two-sided 99 % χ² interval for
    ``runs`` independent 5-dof samples (time samples are correlated, so only the runs count as independent);
    a filter that believes its sensors 25x too much falls outside it."""
    runs = 12
    lo, hi = stats.chi2.ppf([0.005, 0.995], 5 * runs) / runs
    p = OdometryEkfParams()
    assert lo < mean_nees(p, p, runs=runs) < hi
    overconfident = OdometryEkfParams(accel_std_per_rts=0.1, angular_accel_std_per_rts=0.2, pose_std_per_rts=0.001,
                                      yaw_std_per_rts=0.0004, wheel_v_std_mps=0.004, wheel_w_std_radps=0.01,
                                      gyro_std_radps=0.002)
    assert mean_nees(p, overconfident, runs=runs) > hi


def test_odometry_ekf_rejects_bad_input() -> None:
    ekf = OdometryEkf()
    assert ekf.update_wheels(0.1, Twist(0.2, 0.0))
    assert not ekf.update_wheels(0.05, Twist(0.2, 0.0))  # older than the filter
    assert not ekf.update_wheels(0.2, Twist(float("nan"), 0.0))
    assert not ekf.update_imu(ImuSample(float("inf"), 0.0, 0.0, 0.0))
    assert not ekf.update_scan_match(0.3, Pose2D(float("nan"), 0.0, 0.0), 0.1)
    assert not ekf.update_scan_match(0.3, Pose2D(0.01, 0.0, 0.0), 0.0)
    assert ekf.rejected == 5
    assert np.isfinite(ekf.state).all() and np.isfinite(ekf.covariance).all()
    with pytest.raises(ConfigError):
        OdometryEkfParams(gyro_std_radps=-1.0)
    with pytest.raises(ConfigError, match="square") as err:  # a variance of inf would poison every update
        OdometryEkfParams(wheel_v_std_mps=1e200)
    assert err.value.path == "localization.odometry.wheel_v_std_mps"
    # scan matches over tiny intervals: the rate's variance overflows or the interval squared is 0; refused, not fused
    assert not ekf.update_scan_match(0.3, Pose2D(0.01, 0.0, 0.0), 1e-300, np.eye(3))
    assert not ekf.update_scan_match(0.3, Pose2D(0.01, 0.0, 0.0), 1e-160, np.eye(3) * 1e-10)
    assert ekf.rejected == 7 and np.isfinite(ekf.state).all()


def test_fusion_in_the_simulator(living_room_drive) -> None:  # type: ignore[no-untyped-def]
    """Wheels + gyro + ICP on the simulated lap: the fused heading and position stay close to the truth
    (expressed in the odometry frame, which starts at the true start pose)."""
    rec = living_room_drive
    start = as_array(rec.truth[0])
    ekf = OdometryEkf(now=rec.scans[0].t)
    imu = iter(rec.imu)
    sample = next(imu)
    pos_err, yaw_err, wheel_err = [], [], []
    for k in range(1, len(rec.scans)):
        t0, t1 = rec.scans[k - 1].t, rec.scans[k].t
        # wheel odometry's twist over the scan interval, at the IMU rate in between
        inc = relative(as_array(rec.odom[k - 1]), as_array(rec.odom[k]))
        while sample.t <= t1:
            if sample.t > ekf.t:
                ekf.update_imu(sample)
            sample = next(imu, ImuSample(math.inf, 0.0, 0.0, 0.0))
        ekf.update_wheels(t1, Twist(math.hypot(inc[0], inc[1]) / (t1 - t0), inc[2] / (t1 - t0)))
        m = icp(scan_points(rec.scans[k]), scan_points(rec.scans[k - 1]), as_pose(inc))
        if m.ok:
            ekf.update_scan_match(t1, m.pose, t1 - t0, m.covariance)
        truth = relative(start, as_array(rec.truth[k]))
        est = as_array(ekf.estimate.pose)
        pos_err.append(math.hypot(*(est[:2] - truth[:2])))
        yaw_err.append(abs(float(wrap_angle(est[2] - truth[2]))))
        wheel_err.append(math.hypot(*(as_array(rec.odom[k])[:2] - truth[:2])))
    assert max(pos_err) < 0.15 and max(yaw_err) < 0.05
    assert pos_err[-1] < wheel_err[-1]  # better than the wheels alone at the end of the lap
    assert ekf.rejected == 0


def test_map_ekf_fuses_amcl_and_gates_outliers() -> None:
    ekf = MapEkf()
    with pytest.raises(NavigationError):
        ekf.reset(PoseEstimate(0.0, Pose2D(float("nan"), 0, 0), np.eye(3)), Pose2D())
    ekf.reset(PoseEstimate(0.0, Pose2D(1.0, 2.0, 0.5), np.diag([0.01, 0.01, 0.01])), Pose2D(0.0, 0.0, 0.0))
    # drive 1 m forward in odom: map pose follows along its own heading
    assert ekf.predict(1.0, Pose2D(1.0, 0.0, 0.0))
    e = ekf.estimate.pose
    assert (e.x_m, e.y_m) == pytest.approx((1.0 + math.cos(0.5), 2.0 + math.sin(0.5)))
    grown = ekf.estimate.covariance[0, 0]
    assert ekf.update(PoseEstimate(1.0, Pose2D(e.x_m + 0.05, e.y_m, 0.5), np.diag([0.01, 0.01, 0.01])))
    assert ekf.estimate.covariance[0, 0] < grown and e.x_m < ekf.estimate.pose.x_m < e.x_m + 0.05
    assert not ekf.update(PoseEstimate(1.0, Pose2D(e.x_m + 5.0, e.y_m, 0.5), np.diag([1e-4] * 3)))
    assert ekf.gated == 1
    assert not ekf.update(PoseEstimate(1.0, Pose2D(float("nan"), 0, 0), np.eye(3)))
    # map→odom composed with odometry gives the map pose
    corr = ekf.map_to_odom()
    assert compose(as_array(corr), [1.0, 0.0, 0.0]) == pytest.approx(as_array(ekf.estimate.pose))


def test_the_update_is_filterpys_to_the_bit() -> None:
    """`kalman_update` leaves out filterpy's bookkeeping and inverts a one-row innovation as ``1 / s``: on random
    states and covariances, with the measurements the filter makes (the gyro's one row, the wheels' and the scan
    matcher's two), it answers exactly as `ExtendedKalmanFilter.update`; a singular innovation is refused as scipy
    refuses it."""
    rng = np.random.default_rng(11)
    h_twist = np.array([[0.0, 0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]])
    h_gyro = h_twist[1:]
    for trial in range(400):
        a = rng.normal(size=(5, 5)) * 10.0 ** rng.uniform(-4, 1)
        p = a @ a.T + np.diag(rng.uniform(1e-12, 1e-3, 5))
        x = rng.normal(size=5)
        h = h_gyro if trial % 2 else h_twist
        r = np.diag(rng.uniform(1e-8, 1e-2, h.shape[0]))
        z = rng.normal(size=h.shape[0])
        kf = ExtendedKalmanFilter(dim_x=5, dim_z=h.shape[0])
        kf.x, kf.P = x.copy(), p.copy()
        kf.update(z, lambda _x, h=h: h, h.__matmul__, R=r)
        got_x, got_p = kalman_update(x, p, z, h, r)
        assert got_x.tobytes() == kf.x.tobytes() and got_p.tobytes() == kf.P.tobytes(), trial
    with pytest.raises(np.linalg.LinAlgError):
        kalman_update(np.zeros(5), np.zeros((5, 5)), np.zeros(1), h_gyro, np.zeros((1, 1)))
