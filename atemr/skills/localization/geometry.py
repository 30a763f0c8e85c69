"""SE(2) pose algebra on ``(..., 3)`` arrays ``[x_m, y_m, yaw_rad]`` and on `Pose2D`.

``compose(a, b)`` is ``a ⊕ b`` (``b`` expressed in ``a``'s frame, as a transform chain); ``relative(a, b)``
is ``a⁻¹ ⊕ b``, the motion that takes ``a`` to ``b`` seen from ``a``. Every scan matcher, filter and the
SLAM front end speak in these, so they live in one place.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from atemr.msgs import Pose2D
from atemr.skills.diff_drive import wrap_angle

FloatArray = NDArray[np.float64]


def as_array(pose: Pose2D) -> FloatArray:
    """``[x, y, yaw]`` of a pose."""
    return np.array([pose.x_m, pose.y_m, pose.yaw_rad], dtype=np.float64)


def as_pose(a: ArrayLike) -> Pose2D:
    """A `Pose2D` from ``[x, y, yaw]`` (yaw wrapped to [-π, π))."""
    x, y, th = np.asarray(a, dtype=np.float64).reshape(3).tolist()
    return Pose2D(x, y, wrap_angle(th))


def is_finite_pose(pose: Pose2D) -> bool:
    """Whether all three numbers are finite (a NaN pose must never reach a filter)."""
    return math.isfinite(pose.x_m) and math.isfinite(pose.y_m) and math.isfinite(pose.yaw_rad)


#: The shape of one pose. For one pose each, the algebra runs on plain floats: a dozen ufunc calls on three numbers
#: cost ten times more, and the robot composes single poses tens of times a tick. The same operations in the same
#: order, so the same bits as the array path (``tests/skills/localization/test_geometry.py``).
_ONE = (3,)


def compose(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``a ⊕ b`` (broadcasts over leading axes)."""
    a_, b_ = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a_.shape == _ONE and b_.shape == _ONE:
        ax, ay, ath = a_.tolist()
        bx, by, bth = b_.tolist()
        cos, sin = math.cos(ath), math.sin(ath)
        return np.array((ax + cos * bx - sin * by, ay + sin * bx + cos * by, wrap_angle(ath + bth)))
    c, s = np.cos(a_[..., 2]), np.sin(a_[..., 2])
    x = a_[..., 0] + c * b_[..., 0] - s * b_[..., 1]
    y = a_[..., 1] + s * b_[..., 0] + c * b_[..., 1]
    return np.stack([x, y, wrap_angle(a_[..., 2] + b_[..., 2])], axis=-1)


def inverse(a: ArrayLike) -> FloatArray:
    """``a⁻¹`` such that ``a ⊕ a⁻¹`` is the identity."""
    a_ = np.asarray(a, dtype=np.float64)
    if a_.shape == _ONE:
        ax, ay, ath = a_.tolist()
        cos, sin = math.cos(ath), math.sin(ath)
        return np.array((-cos * ax - sin * ay, sin * ax - cos * ay, wrap_angle(-ath)))
    c, s = np.cos(a_[..., 2]), np.sin(a_[..., 2])
    x = -c * a_[..., 0] - s * a_[..., 1]
    y = s * a_[..., 0] - c * a_[..., 1]
    return np.stack([x, y, wrap_angle(-a_[..., 2])], axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``a⁻¹ ⊕ b``: where ``b`` is seen from ``a``."""
    return compose(inverse(a), b)


def transform_points(pose: ArrayLike, points: ArrayLike) -> FloatArray:
    """Points ``(M, 2)`` given in the frame ``pose`` → the parent frame."""
    p = np.asarray(pose, dtype=np.float64).reshape(3)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    c, s = math.cos(p[2]), math.sin(p[2])
    return np.column_stack([p[0] + c * pts[:, 0] - s * pts[:, 1], p[1] + s * pts[:, 0] + c * pts[:, 1]])


__all__ = ["as_array", "as_pose", "compose", "inverse", "is_finite_pose", "relative", "transform_points"]
