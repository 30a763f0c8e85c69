"""The odometry motion model (Probabilistic Robotics, table 5.6: ``sample_motion_model_odometry``).

The motion between two odometry poses is split into a first rotation, a translation and a second
rotation; each is perturbed with noise whose variance grows with the motion itself (alpha1: rotation
from rotation, alpha2: rotation from translation, alpha3: translation from translation, alpha4:
translation from rotation), and the perturbed motion is applied to every particle at once. As in ROS
amcl's ``diff-corrected`` model, the rotation noise of a reversing robot is taken from the smaller of
the rotation and its reverse, so backing up is not mistaken for a half turn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.msgs import Pose2D
from atemr.skills.diff_drive import wrap_angle
from atemr.skills.localization.geometry import FloatArray


@dataclass(frozen=True)
class OdometryNoise:
    """alpha1..alpha4 (ROS amcl ``odom_alpha1..4``); defaults fit the simulator's 2 % slip, 1 % encoders."""

    alpha1: float = 0.05
    alpha2: float = 0.05
    alpha3: float = 0.05
    alpha4: float = 0.02

    def __post_init__(self) -> None:
        for name in ("alpha1", "alpha2", "alpha3", "alpha4"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"must be a finite number >= 0, got {value!r}", path=f"localization.{name}")


def _min_abs_rot(a: FloatArray | float) -> FloatArray:
    """|a| or |a − π|, whichever is smaller (reversing is not a half turn)."""
    a_ = np.asarray(a, dtype=np.float64)
    return np.minimum(np.abs(wrap_angle(a_)), np.abs(wrap_angle(a_ - np.pi)))


def sample_motion_model_odometry(
    particles: FloatArray, odom_before: Pose2D, odom_after: Pose2D, noise: OdometryNoise, rng: np.random.Generator
) -> FloatArray:
    """Move ``particles`` ``(N, 3)`` by the odometry motion ``before → after`` with sampled noise (new array)."""
    dx = odom_after.x_m - odom_before.x_m
    dy = odom_after.y_m - odom_before.y_m
    trans = math.hypot(dx, dy)
    rot1 = float(wrap_angle(math.atan2(dy, dx) - odom_before.yaw_rad)) if trans > 0.01 else 0.0
    rot2 = float(wrap_angle(odom_after.yaw_rad - odom_before.yaw_rad - rot1))
    r1n, r2n = float(_min_abs_rot(rot1)), float(_min_abs_rot(rot2))
    a = noise
    n = particles.shape[0]
    z = rng.standard_normal((3, n))
    rot1_hat = rot1 - z[0] * math.sqrt(a.alpha1 * r1n**2 + a.alpha2 * trans**2)
    trans_hat = trans - z[1] * math.sqrt(a.alpha3 * trans**2 + a.alpha4 * (r1n**2 + r2n**2))
    rot2_hat = rot2 - z[2] * math.sqrt(a.alpha1 * r2n**2 + a.alpha2 * trans**2)
    th = particles[:, 2] + rot1_hat
    out = np.empty_like(particles)
    out[:, 0] = particles[:, 0] + trans_hat * np.cos(th)
    out[:, 1] = particles[:, 1] + trans_hat * np.sin(th)
    out[:, 2] = wrap_angle(th + rot2_hat)
    return out


__all__ = ["OdometryNoise", "sample_motion_model_odometry"]
