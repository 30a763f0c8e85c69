"""Differential drive kinematics: twist ↔ wheel speeds, and wheel motion → odometry by exact arcs.

For wheel radius R and track (wheel separation) L, with left/right wheel speeds ωl, ωr in rad/s:

    v = R (ωr + ωl) / 2          ω = R (ωr − ωl) / L
    ωl = (v − ω L/2) / R         ωr = (v + ω L/2) / R

Odometry assumes the twist is constant over a step (what a wheel-speed sample or an encoder delta
tells us), so the base moves on a circular arc. With Δθ = ω·dt the exact displacement is the chord of
that arc: length v·dt·sinc(Δθ/2), direction θ + Δθ/2. Written with sinc it has no special case at ω = 0
and no cancellation for small Δθ. Every function broadcasts over numpy arrays (particles, candidate
twists); the small classes keep only what must live between ticks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from atemr.errors import ConfigError
from atemr.msgs import Pose2D, Twist, WheelSpeeds

ArrayOrFloat = TypeVar("ArrayOrFloat", float, NDArray[np.float64])

#: KAY's drive (docs/simulator.md#simulated-devices, the base): RMD-L-7015 hub wheels.
DEFAULT_WHEEL_RADIUS_M = 0.085
DEFAULT_TRACK_M = 0.40


def arc_step(
    x: ArrayLike, y: ArrayLike, yaw: ArrayLike, linear_mps: ArrayLike, angular_radps: ArrayLike, *, dt_s: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Poses after moving with a constant twist for ``dt_s``, exactly (arrays broadcast).

    The yaw is not wrapped, so repeated steps keep a continuous heading; wrap for display.
    """
    x_, y_, th = (np.asarray(a, dtype=np.float64) for a in (x, y, yaw))
    v, w, dt = (np.asarray(a, dtype=np.float64) for a in (linear_mps, angular_radps, dt_s))
    dth = w * dt
    chord = v * dt * np.sinc(dth / (2.0 * np.pi))  # np.sinc(u) = sin(πu)/(πu), so this is sin(Δθ/2)/(Δθ/2)
    mid = th + dth / 2.0
    return x_ + chord * np.cos(mid), y_ + chord * np.sin(mid), th + dth


def arc_step_one(x: float, y: float, yaw: float, linear_mps: float, angular_radps: float, *, dt_s: float
                 ) -> tuple[float, float, float]:
    """`arc_step` for one pose, in plain floats: the odometry filters step one pose 100 times a simulated second,
    where a dozen ufunc calls on single numbers cost ten times the arithmetic. The same operations in the same
    order, with `np.sinc`'s own substitute for 0, so the same bits as `arc_step`
    (``tests/skills/test_diff_drive.py``). A step whose angles are not finite takes `arc_step` itself: ``math``
    raises on an infinite angle where numpy answers NaN."""
    dth = angular_radps * dt_s
    mid = yaw + dth / 2.0
    if not (math.isfinite(dth) and math.isfinite(mid)):
        nx, ny, nth = arc_step(x, y, yaw, linear_mps, angular_radps, dt_s=dt_s)
        return float(nx), float(ny), float(nth)
    u = math.pi * (dth / (2.0 * math.pi))
    u = u if u != 0.0 else _EPS
    chord = linear_mps * dt_s * (math.sin(u) / u)
    return x + chord * math.cos(mid), y + chord * math.sin(mid), yaw + dth


#: What `np.sinc` puts in place of 0 (its ``finfo(float64).eps``).
_EPS = float(np.finfo(np.float64).eps)


def wrap_angle(a: ArrayOrFloat) -> ArrayOrFloat:
    """Angle(s) wrapped to [-π, π)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class DiffDrive:
    """The drive's geometry and wheel speed limit; converts between twists and wheel speeds."""

    wheel_radius_m: float = DEFAULT_WHEEL_RADIUS_M
    track_m: float = DEFAULT_TRACK_M
    #: Wheel speed limit in rad/s (1.8 m/s spec maximum over 0.085 m ≈ 21 rad/s); inf: no limit.
    max_wheel_radps: float = 1.8 / DEFAULT_WHEEL_RADIUS_M

    def __post_init__(self) -> None:
        for what in ("wheel_radius_m", "track_m", "max_wheel_radps"):
            value = getattr(self, what)
            if not (value > 0.0) or math.isnan(value):
                raise ConfigError(f"diff drive: {what} must be positive, got {value!r}")

    def wheel_speeds(
        self, linear_mps: ArrayLike, angular_radps: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(left, right) wheel speeds in rad/s, scaled down together if one exceeds the limit.

        Scaling both keeps the curvature (the path's shape) and only slows the base down, which is
        what an operator expects when asking for more than the wheels can give.
        """
        v = np.asarray(linear_mps, dtype=np.float64)
        w = np.asarray(angular_radps, dtype=np.float64)
        half = w * self.track_m / 2.0
        left = (v - half) / self.wheel_radius_m
        right = (v + half) / self.wheel_radius_m
        peak = np.maximum(np.abs(left), np.abs(right))
        scale = np.where(peak > self.max_wheel_radps, self.max_wheel_radps / np.maximum(peak, 1e-300), 1.0)
        return left * scale, right * scale

    def twist(self, left_radps: ArrayLike, right_radps: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(linear m/s, angular rad/s) of the base for the given wheel speeds."""
        wl = np.asarray(left_radps, dtype=np.float64)
        wr = np.asarray(right_radps, dtype=np.float64)
        return self.wheel_radius_m * (wr + wl) / 2.0, self.wheel_radius_m * (wr - wl) / self.track_m

    def command(self, twist: Twist) -> WheelSpeeds:
        """The wheel speed command for one twist (the message the motor driver takes).

        `wheel_speeds` in plain floats: called once per 50 Hz tick, where numpy's per-call overhead
        is most of the cost (tests check both agree).
        """
        half = twist.angular_radps * self.track_m / 2.0
        left = (twist.linear_mps - half) / self.wheel_radius_m
        right = (twist.linear_mps + half) / self.wheel_radius_m
        peak = max(abs(left), abs(right))
        if peak > self.max_wheel_radps:
            scale = self.max_wheel_radps / peak
            left, right = left * scale, right * scale
        return WheelSpeeds(left, right)

    def measured(self, wheels: WheelSpeeds) -> Twist:
        """The base twist that measured wheel speeds mean."""
        v, w = self.twist(wheels.left_radps, wheels.right_radps)
        return Twist(float(v), float(w))


@dataclass
class Odometry:
    """Dead reckoning from wheel feedback: integrates exact arcs from speeds or encoder angles.

    Feed it either wheel speed samples with their time (`update_speeds`) or cumulative wheel angles
    (`update_angles`, better: no sampling error between samples). Non-finite or out-of-order feedback
    is ignored: the pose is kept, the update returns ``False`` and ``rejected`` counts it, so a glitching
    encoder cannot throw the pose to NaN, and the motor driver's health check sees the count.
    """

    drive: DiffDrive = field(default_factory=DiffDrive)
    pose: Pose2D = field(default_factory=Pose2D)
    twist: Twist = field(default_factory=Twist)
    distance_m: float = 0.0
    rejected: int = 0
    _last_t: float | None = None
    _last_angles: tuple[float, float] | None = None

    def reset(self, pose: Pose2D | None = None) -> None:
        """Start again from ``pose`` (origin by default); the next sample only sets the reference."""
        self.pose = pose or Pose2D()
        self.twist = Twist()
        self.distance_m = 0.0
        self._last_t = None
        self._last_angles = None

    def update_speeds(self, now: float, wheels: WheelSpeeds) -> bool:
        """Advance with wheel speeds measured at ``now``, held since the previous sample."""
        if not (math.isfinite(now) and math.isfinite(wheels.left_radps) and math.isfinite(wheels.right_radps)):
            self.rejected += 1
            return False
        if self._last_t is not None and now < self._last_t:
            self.rejected += 1
            return False
        v, w = self.drive.twist(wheels.left_radps, wheels.right_radps)
        dt = 0.0 if self._last_t is None else now - self._last_t
        self._last_t = now
        self._advance(float(v), float(w), dt)
        return True

    def update_angles(self, now: float, left_rad: float, right_rad: float) -> bool:
        """Advance with cumulative wheel angles (encoders) read at ``now``."""
        if not (math.isfinite(now) and math.isfinite(left_rad) and math.isfinite(right_rad)):
            self.rejected += 1
            return False
        last, last_t = self._last_angles, self._last_t
        self._last_angles, self._last_t = (left_rad, right_rad), now
        if last is None or last_t is None:
            return True
        dt = now - last_t
        dl, dr = left_rad - last[0], right_rad - last[1]
        ds, dth = self.drive.twist(dl, dr)  # per-step distance and heading change
        if dt > 0.0:
            self._advance(float(ds) / dt, float(dth) / dt, dt)
        else:
            self._advance(float(ds), float(dth), 1.0)
            self.twist = Twist()
        return True

    def _advance(self, v: float, w: float, dt: float) -> None:
        x, y, th = arc_step_one(self.pose.x_m, self.pose.y_m, self.pose.yaw_rad, v, w, dt_s=dt)
        self.pose = Pose2D(x, y, wrap_angle(th))
        self.twist = Twist(v, w)
        self.distance_m += abs(v) * dt


__all__ = [
    "DEFAULT_TRACK_M", "DEFAULT_WHEEL_RADIUS_M", "DiffDrive", "Odometry", "arc_step", "arc_step_one", "wrap_angle",
]
