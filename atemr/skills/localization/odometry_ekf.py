"""EKF odometry fusion (`odom` frame) and the map-frame EKF that fuses AMCL (filterpy).

**OdometryEkf** — state ``[x, y, θ, v, ω]`` in the odometry frame (starts at the origin, drifts slowly,
never jumps: what the motion controller and the local planner want). The prediction moves the pose on
the exact arc of the current twist (`atemr.skills.diff_drive.arc_step`, the same kinematics as wheel
odometry) and lets the twist wander as a random walk (``accel_std``, ``angular_accel_std``), plus a
little pose noise for slip. Three sensors correct the twist, each with its own noise:

* wheel odometry: ``[v, ω]`` from the wheels' speeds (`DiffDrive.measured`);
* IMU: ``ω`` from the gyro (not fooled by a slipping wheel), less its bias;
* scan matcher: the ICP increment between consecutive scans, as ``[v, ω] = Δ/Δt`` with the ICP
  covariance (Censi's estimate) scaled to a rate; a failed match is simply not used.

**The gyro's bias** is learned whenever the wheels say the robot stands still (every wheel measurement zero, or a
step of the motors' speed readings from it, for ``gyro_bias_settle_s``: `stands_still`): the gyro then reads its
bias and its noise. The estimate is the plain mean of those readings until they span ``gyro_bias_tau_s`` (so a robot
that has just woken up knows its bias within a second), then an exponential average with that time constant, which
follows the bias as it drifts with temperature. Left in, a bias of a tenth of a degree a second is what the fusion
trusts most (the gyro's noise is five times smaller than the wheels'): a robot waiting for its next command would
turn in ``odom`` by several degrees a minute, and its map pose with it, until only a scan match could pull it back.
With the bias out it stands still in ``odom`` too, so localization has nothing to correct while the robot waits. A
rate further than ``gyro_bias_gate_radps`` from the estimate is a turn, not a bias (a robot lifted and turned by
hand, its wheels still): it is fused, not learned.

Measurements of the twist, rather than of the pose, are what the ``differential`` mode of ROS
robot_localization does with relative sensors: a sensor that restarts or a scan matcher that fails
once cannot pull the pose, only stop contributing.

**MapEkf** — state ``[x, y, θ]`` in the map frame. It predicts with the odometry increment since the last
call (noise growing with distance and rotation, alpha model) and corrects with AMCL's pose and
covariance, gating outliers by their Mahalanobis distance. Its output is the robot's map pose and the
``map → odom`` correction (``map_pose ⊕ odom_pose⁻¹``) the rest of the robot composes with odometry.

Bad input (NaN, a measurement older than the filter, a non-positive-definite covariance) is dropped
and counted in ``rejected``: a glitching sensor must never turn the estimate into NaN.

Both hold their state in filterpy's `ExtendedKalmanFilter`. The odometry EKF, which runs 150 times a simulated
second, does its own prediction in plain floats and its corrections with `kalman_update` (filterpy's update without
its bookkeeping): the same operations, so the same bits, at about two thirds of the cost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from scipy import linalg

from atemr.errors import ConfigError, NavigationError
from atemr.msgs import ImuSample, Pose2D, Twist
from atemr.skills.diff_drive import arc_step_one, wrap_angle
from atemr.skills.localization.amcl import PoseEstimate
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, compose, inverse, is_finite_pose, relative


def _check_positive(obj: object, names: tuple[str, ...], section: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"{section}.{name}")


@dataclass(frozen=True)
class OdometryEkfParams:
    """Noise model of the odometry EKF (standard deviations; ``*_per_rtS`` are per √s)."""

    accel_std_per_rts: float = 0.5
    angular_accel_std_per_rts: float = 1.0
    pose_std_per_rts: float = 0.005
    yaw_std_per_rts: float = 0.002
    wheel_v_std_mps: float = 0.02
    wheel_w_std_radps: float = 0.05
    gyro_std_radps: float = 0.01
    #: Floor under the scan matcher's (optimistic) covariance, as a rate.
    icp_v_std_min_mps: float = 0.02
    icp_w_std_min_radps: float = 0.01
    #: The gyro's bias, learned while the wheels stand still (module docstring): the time constant of its average,
    #: how long the wheels must have read zero first, and how far from the estimate a reading is a turn instead.
    gyro_bias_tau_s: float = 10.0
    gyro_bias_settle_s: float = 0.5
    gyro_bias_gate_radps: float = 0.05
    #: A wheel twist this close to zero is a robot standing (`stands_still`): the motors report their speed in steps
    #: of 1°/s, so a standing motor may read a step either way (1.5 mm/s on a 0.085 m wheel; two wheels a step
    #: apart either way turn the base by 0.0074 rad/s on a 0.4 m track).
    still_mps: float = 0.002
    still_radps: float = 0.008

    def __post_init__(self) -> None:
        _check_positive(self, tuple(self.__dataclass_fields__), "localization.odometry")
        for name in self.__dataclass_fields__:  # the filter works with variances
            if not math.isfinite(getattr(self, name) * getattr(self, name)):
                raise ConfigError(f"is too large: its square is not a finite number, got {getattr(self, name)!r}",
                                  path=f"localization.odometry.{name}")


def _read_only(a: FloatArray) -> FloatArray:
    a.setflags(write=False)
    return a


#: Wheels that have not reported for this long (s) no longer say the robot stands (the motors answer at 50-100 Hz).
WHEELS_SILENT_S = 0.2

#: What the sensors measure of ``[x, y, θ, v, ω]``: the twist (wheels, scan matcher), the yaw rate (gyro).
_H_TWIST = _read_only(np.array([[0.0, 0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]]))
_H_GYRO = _read_only(np.array([[0.0, 0.0, 0.0, 0.0, 1.0]]))
_IDENTITY = _read_only(np.eye(5))
_ZEROS = _read_only(np.zeros((5, 5)))


def kalman_update(x: FloatArray, p: FloatArray, z: FloatArray, h: FloatArray, r: FloatArray
                  ) -> tuple[FloatArray, FloatArray]:
    """The state and covariance after measuring ``z`` of ``h @ x`` with noise ``r``: filterpy's
    `ExtendedKalmanFilter.update` for a linear measurement (Joseph form), the same numpy and scipy operations in
    the same order, so the same bits (a test holds it to filterpy's). It leaves out what filterpy keeps for its
    history (copies of ``z``, ``x`` and ``P``, the gain and the innovation), which cost a third of an update at 150
    updates a simulated second; a one-row measurement (the gyro's) is inverted as ``1 / s``, which is what
    `scipy.linalg.inv` answers for a positive finite ``s``, at a tenth of its cost."""
    pht = np.dot(p, h.T)
    s = np.dot(h, pht) + r
    # scipy decides anything else (and refuses a singular or non-finite s)
    si = np.array([[1.0 / float(s[0, 0])]]) if s.shape == (1, 1) and 0.0 < s[0, 0] < math.inf else linalg.inv(s)
    k = pht.dot(si)
    x = x + np.dot(k, z - h @ x)
    i_kh = _IDENTITY - np.dot(k, h)
    p = np.dot(i_kh, p).dot(i_kh.T) + np.dot(k, r).dot(k.T)
    return x, p


class OdometryEkf:
    """Wheel odometry + IMU yaw rate + scan-matcher increments → pose and twist in ``odom``."""

    def __init__(self, params: OdometryEkfParams | None = None, *, now: float = 0.0) -> None:
        self.params = params or OdometryEkfParams()
        self.kf = ExtendedKalmanFilter(dim_x=5, dim_z=2)
        self.kf.x = np.zeros(5)
        self.kf.P = np.diag([1e-9, 1e-9, 1e-9, 0.01, 0.01])
        self.t = now
        self.rejected = 0
        p = self.params
        #: The prediction's noise per second (its diagonal), and the wheels' and the gyro's fixed noise.
        self._q_per_s = (p.pose_std_per_rts**2, p.pose_std_per_rts**2, p.yaw_std_per_rts**2,
                         p.accel_std_per_rts**2, p.angular_accel_std_per_rts**2)
        self._r_wheels = np.diag([p.wheel_v_std_mps**2, p.wheel_w_std_radps**2])
        self._r_gyro = np.array([[p.gyro_std_radps**2]])
        #: The gyro's bias as learned so far (rad/s), subtracted from every reading.
        self.gyro_bias_radps = 0.0
        self._still_since: float | None = None  # when the wheels last started reading zero (None: they move)
        self._wheels_t = -math.inf  # the time of the last wheel reading
        self._gyro_t: float | None = None  # the time of the last gyro reading fused
        self._bias_readings = 0  # how many readings the bias was learned from

    # -- prediction ------------------------------------------------------------------------------
    def predict_to(self, now: float) -> bool:
        """Advance the state to ``now``; False (and nothing changes) if ``now`` is NaN or in the past."""
        if not math.isfinite(now) or now < self.t:
            self.rejected += 1
            return False
        dt = now - self.t
        if dt == 0.0:
            return True
        # Plain floats: this runs 100 times a simulated second, and a numpy scalar's arithmetic costs five times a
        # float's, for the same bits.
        x0, x1, th, v, w = self.kf.x.tolist()
        mid = th + w * dt / 2.0
        c, s = math.cos(mid), math.sin(mid)
        # Copies of fixed templates, filled in element by element: np.eye and a fancy-indexed diagonal cost a
        # microsecond each, a third of the prediction (the same matrices, so the same bits).
        f = _IDENTITY.copy()  # Jacobian of the midpoint form of the arc (exact to second order)
        f[0, 2], f[0, 3], f[0, 4] = -v * dt * s, dt * c, -v * dt * dt / 2.0 * s
        f[1, 2], f[1, 3], f[1, 4] = v * dt * c, dt * s, v * dt * dt / 2.0 * c
        f[2, 4] = dt
        q = _ZEROS.copy()
        q0, q1, q2, q3, q4 = self._q_per_s
        q[0, 0], q[1, 1], q[2, 2], q[3, 3], q[4, 4] = q0 * dt, q1 * dt, q2 * dt, q3 * dt, q4 * dt
        nx, ny, nth = arc_step_one(x0, x1, th, v, w, dt_s=dt)
        self.kf.P = f @ self.kf.P @ f.T + q
        self.kf.x = np.array([nx, ny, wrap_angle(nth), v, w])
        self.t = now
        return True

    # -- corrections -----------------------------------------------------------------------------
    def _update(self, now: float, z: tuple[float, ...], h: FloatArray, r: FloatArray) -> bool:
        """Correct with measurement ``z`` of ``h @ x`` (noise ``r``), after predicting to ``now``. The measurements
        are linear, so the Jacobian is ``h`` itself."""
        if not all(map(math.isfinite, z)):
            self.rejected += 1
            return False
        if not self.predict_to(now):  # counts its own rejection
            return False
        self.kf.x, self.kf.P = kalman_update(self.kf.x, self.kf.P, np.array(z), h, r)
        return True

    def update_wheels(self, now: float, twist: Twist) -> bool:
        """Wheel odometry's twist (from `DiffDrive.measured`) measured at ``now``."""
        if not self._update(now, (twist.linear_mps, twist.angular_radps), _H_TWIST, self._r_wheels):
            return False
        if not self.stands_still(twist):
            self._still_since = None
        elif self._still_since is None:
            self._still_since = now
        self._wheels_t = now
        return True

    def stands_still(self, twist: Twist) -> bool:
        """Whether a wheel twist means a robot standing: zero, or within a step of the motors' speed readings."""
        p = self.params
        return abs(twist.linear_mps) <= p.still_mps and abs(twist.angular_radps) <= p.still_radps

    @property
    def standing(self) -> bool:
        """Whether the wheels have read zero for at least ``gyro_bias_settle_s`` (the gyro reads its bias), and still
        do: wheels silent for longer than `WHEELS_SILENT_S` (a motor driver that lost its motors) say nothing, and a
        robot pushed about meanwhile must not teach its turns as the bias."""
        return (self._still_since is not None and self.t - self._still_since >= self.params.gyro_bias_settle_s
                and self.t - self._wheels_t <= WHEELS_SILENT_S)

    def update_imu(self, sample: ImuSample) -> bool:
        """The gyro's yaw rate, less its bias; while the robot stands, the reading also teaches the bias."""
        rate, last = sample.yaw_rate_radps, self._gyro_t
        if not self._update(sample.t, (rate - self.gyro_bias_radps,), _H_GYRO, self._r_gyro):
            return False
        self._gyro_t = sample.t
        p = self.params
        if self.standing and last is not None and abs(rate - self.gyro_bias_radps) <= p.gyro_bias_gate_radps:
            self._bias_readings += 1
            weight = max(1.0 / self._bias_readings, min(1.0, (sample.t - last) / p.gyro_bias_tau_s))
            self.gyro_bias_radps += weight * (rate - self.gyro_bias_radps)
        return True

    def update_scan_match(self, now: float, delta: Pose2D, dt_s: float, covariance: FloatArray | None = None) -> bool:
        """A scan-matcher increment ``delta`` (later scan in the earlier scan's frame) over ``dt_s`` seconds."""
        if not (is_finite_pose(delta) and math.isfinite(dt_s) and dt_s > 0):
            self.rejected += 1
            return False
        p = self.params
        var_v, var_w = p.icp_v_std_min_mps**2, p.icp_w_std_min_radps**2
        if covariance is not None:
            cov = np.asarray(covariance, dtype=np.float64)
            if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
                self.rejected += 1
                return False
            rate2 = dt_s * dt_s
            if rate2 == 0.0:  # too short an interval to be a rate
                self.rejected += 1
                return False
            var_v = max(var_v, float(cov[0, 0]) / rate2)
            var_w = max(var_w, float(cov[2, 2]) / rate2)
        if not (math.isfinite(var_v) and math.isfinite(var_w)):  # a tiny dt can overflow the rate's variance
            self.rejected += 1
            return False
        chord = math.hypot(delta.x_m, delta.y_m) * (1.0 if delta.x_m >= 0 else -1.0)
        return self._update(now, (chord / dt_s, delta.yaw_rad / dt_s), _H_TWIST, np.diag([var_v, var_w]))

    # -- output ----------------------------------------------------------------------------------
    @property
    def estimate(self) -> PoseEstimate:
        """Pose in ``odom`` and its covariance at the filter's time."""
        return PoseEstimate(self.t, self.pose, np.array(self.kf.P[:3, :3]))

    @property
    def pose(self) -> Pose2D:
        """Pose in ``odom`` at the filter's time (`estimate` without copying the covariance)."""
        return as_pose(self.kf.x[:3])

    @property
    def state(self) -> FloatArray:
        """``[x, y, θ, v, ω]`` (a copy)."""
        return np.array(self.kf.x)

    @property
    def covariance(self) -> FloatArray:
        """The full 5×5 covariance (a copy)."""
        return np.array(self.kf.P)

    @property
    def twist(self) -> Twist:
        return Twist(float(self.kf.x[3]), float(self.kf.x[4]))


@dataclass(frozen=True)
class MapEkfParams:
    """Odometry increment noise (alpha model) and the AMCL gate."""

    trans_from_trans: float = 0.05
    rot_from_rot: float = 0.05
    rot_from_trans: float = 0.05
    #: Floor under AMCL's covariance (a converged cloud is often narrower than the truth).
    amcl_std_min_m: float = 0.03
    amcl_yaw_std_min_rad: float = 0.02
    #: Mahalanobis gate (χ², 3 dof; 16.27 is the 99.9 % quantile).
    gate_chi2: float = 16.27

    def __post_init__(self) -> None:
        _check_positive(self, tuple(self.__dataclass_fields__), "localization.map_ekf")


def _pose_residual(a: FloatArray, b: FloatArray) -> FloatArray:
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    d[2] = wrap_angle(d[2])
    return d


class MapEkf:
    """The robot's pose in ``map``: odometry increments predict it, AMCL corrects it."""

    def __init__(self, params: MapEkfParams | None = None) -> None:
        self.params = params or MapEkfParams()
        self.kf = ExtendedKalmanFilter(dim_x=3, dim_z=3)
        self.kf.x = np.zeros(3)
        self.kf.P = np.eye(3) * 1e6
        self.t = 0.0
        self.initialized = False
        self.rejected = 0
        self.gated = 0
        self._odom: FloatArray | None = None

    def reset(self, estimate: PoseEstimate, odom: Pose2D) -> None:
        """Start (or restart, after relocalization) at ``estimate`` while odometry reads ``odom``."""
        if not (is_finite_pose(estimate.pose) and is_finite_pose(odom)):
            raise NavigationError(f"map EKF: reset needs finite poses, got {estimate.pose} and {odom}")
        self.kf.x = as_array(estimate.pose)
        self.kf.P = self._floored(estimate.covariance)
        self._odom = as_array(odom)
        self.t = estimate.t
        self.initialized = True

    def predict(self, now: float, odom: Pose2D) -> bool:
        """Move by the odometry increment since the last call (odometry in ``odom`` at ``now``)."""
        if not (self.initialized and math.isfinite(now) and is_finite_pose(odom)) or self._odom is None:
            self.rejected += 1
            return False
        o = as_array(odom)
        delta = relative(self._odom, o)
        self._odom = o
        self.t = max(self.t, now)
        trans, rot = math.hypot(delta[0], delta[1]), abs(float(delta[2]))
        p = self.params
        sd_t = p.trans_from_trans * trans
        sd_r = p.rot_from_rot * rot + p.rot_from_trans * trans
        th = float(self.kf.x[2])
        c, s = math.cos(th), math.sin(th)
        f = np.array([[1.0, 0.0, -s * delta[0] - c * delta[1]], [0.0, 1.0, c * delta[0] - s * delta[1]], [0, 0, 1]])
        g = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # increment (robot frame) → map
        q = g @ np.diag([sd_t**2, sd_t**2 * 0.25, sd_r**2]) @ g.T
        self.kf.P = f @ self.kf.P @ f.T + q
        self.kf.x = compose(self.kf.x, delta)
        return True

    def _floored(self, cov: FloatArray) -> FloatArray:
        p = self.params
        c = 0.5 * (np.asarray(cov, dtype=np.float64) + np.asarray(cov, dtype=np.float64).T)
        return c + np.diag([p.amcl_std_min_m**2, p.amcl_std_min_m**2, p.amcl_yaw_std_min_rad**2])

    def update(self, estimate: PoseEstimate) -> bool:
        """Correct with an AMCL estimate taken at the odometry of the last `predict`.

        Returns False if it was rejected: not finite, or outside the Mahalanobis gate (counted in
        ``gated``: many in a row mean AMCL and odometry disagree, which the covariance monitor reports).
        """
        z = as_array(estimate.pose)
        cov = np.asarray(estimate.covariance, dtype=np.float64)
        if not (self.initialized and np.all(np.isfinite(z)) and cov.shape == (3, 3) and np.all(np.isfinite(cov))):
            self.rejected += 1
            return False
        r = self._floored(cov)
        y = _pose_residual(z, self.kf.x)
        s = self.kf.P + r
        if float(y @ np.linalg.solve(s, y)) > self.params.gate_chi2:
            self.gated += 1
            return False
        self.kf.update(z, lambda _x: np.eye(3), lambda x: np.asarray(x, dtype=np.float64), R=r,
                       residual=_pose_residual)
        self.kf.x[2] = wrap_angle(float(self.kf.x[2]))
        return True

    @property
    def estimate(self) -> PoseEstimate:
        return PoseEstimate(self.t, as_pose(self.kf.x), np.array(self.kf.P))

    def map_to_odom(self) -> Pose2D:
        """The correction ``map ⊕ odom⁻¹``: compose it with an odometry pose to get the map pose."""
        if self._odom is None:
            return Pose2D()
        return as_pose(compose(self.kf.x, inverse(self._odom)))


__all__ = ["MapEkf", "MapEkfParams", "OdometryEkf", "OdometryEkfParams", "kalman_update"]
