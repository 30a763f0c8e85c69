"""Differential-drive base physics: wheel speeds in, true pose out, walls and obstacles in the way.

The base does not model motor dynamics: it steps two `WheelMotor` objects (the RMD-L-7015 model,
`atemr.io.motors.model.RmdMotorModel`, in the simulator) and integrates the body from their actual
speeds. The ground is imperfect: each wheel's ground speed is its rim speed reduced by a random slip,
so the true motion drifts from what the encoders say, as on a real floor.

Kinematics (x forward, y left, REP 103): ``v = r (ω_R + ω_L) / 2``, ``ω = r (ω_R − ω_L) / track``,
integrated exactly along the arc for each step. A step whose end pose would overlap a wall, a piece
of furniture or a moving obstacle is cut short where the footprint touches (bisection on the step's
fraction), the base stops there, and a `Collision` event is reported once per contact: a bump is an
event, never a teleport through the wall.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from atemr.errors import ConfigError
from atemr.io.sim.scene import Contact
from atemr.msgs import Pose2D


@runtime_checkable
class WheelMotor(Protocol):
    """What the base needs of a wheel: its actual speed (rad/s, positive drives that side forward) and a
    way to advance its dynamics. `RmdMotorModel` satisfies it."""

    @property
    def speed_radps(self) -> float: ...

    def step(self, dt_s: float) -> None: ...


class MountedWheel:
    """A motor model seen as a wheel: ``direction`` (+1/-1) is the shaft sign that drives that side forward.

    On the ATEMR base the right motor is mirrored (``motors.right_direction = -1``): its shaft turns
    backwards when the robot drives forward. The CAN driver applies the same sign, so wrapping the motor
    emulator's model here keeps both sides consistent. ``set_speed`` takes a forward wheel speed.
    """

    def __init__(self, model: Any, direction: int = 1) -> None:
        if direction not in (1, -1):
            raise ConfigError(f"direction must be +1 or -1, got {direction!r}", path="wheel direction")
        self.model = model
        self.direction = direction

    @property
    def speed_radps(self) -> float:
        """Forward wheel speed: the shaft speed times the mounting sign."""
        return self.direction * float(self.model.speed_radps)

    def step(self, dt_s: float) -> None:
        self.model.step(dt_s)

    def set_speed(self, forward_radps: float) -> None:
        """Command a forward wheel speed (the motor gets it with the mounting sign)."""
        self.model.set_speed(self.direction * forward_radps)


@dataclass(frozen=True)
class BaseParams:
    """Geometry and imperfections of the base (defaults: the ATEMR base of the thesis)."""

    wheel_radius_m: float = 0.085
    track_m: float = 0.40
    footprint_radius_m: float = 0.25
    max_speed_mps: float = 1.6
    #: Typical fraction of rim speed lost to slip (std of a slowly varying random process per wheel).
    slip_std: float = 0.02
    #: How fast the slip changes (time constant of that process), s.
    slip_time_constant_s: float = 0.5
    #: Standard deviation of the encoder speed error as a fraction of the wheel speed (odometry noise).
    odom_noise_std: float = 0.01

    def __post_init__(self) -> None:
        for name in ("wheel_radius_m", "track_m", "footprint_radius_m", "max_speed_mps", "slip_time_constant_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"base.{name}")
        for name in ("slip_std", "odom_noise_std"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 <= value < 0.5):
                raise ConfigError(f"must be within [0, 0.5), got {value!r}", path=f"base.{name}")


@dataclass(frozen=True)
class Collision:
    """The robot touched something at time ``t`` while moving; ``what`` names it (``wall``, ``sofa``, ...) and
    ``part`` which part of the robot did (``base``, ``mast``, ``tablet``; empty when only a footprint is known)."""

    t: float
    pose: Pose2D
    what: str
    part: str = ""


#: Signed clearance of the footprint at a point (negative: overlapping), and what is nearest.
ClearanceFn = Callable[[float, float], Contact]


def integrate_arc(pose: Pose2D, v_mps: float, w_radps: float, dt_s: float) -> Pose2D:
    """Exact pose after moving at constant (v, ω) for ``dt_s`` (a straight line when ω ≈ 0)."""
    th = pose.yaw_rad
    dth = w_radps * dt_s
    if abs(dth) < 1e-9:
        x = pose.x_m + v_mps * dt_s * math.cos(th + dth / 2)
        y = pose.y_m + v_mps * dt_s * math.sin(th + dth / 2)
    else:
        radius = v_mps / w_radps
        x = pose.x_m + radius * (math.sin(th + dth) - math.sin(th))
        y = pose.y_m - radius * (math.cos(th + dth) - math.cos(th))
    yaw = math.atan2(math.sin(th + dth), math.cos(th + dth))
    return Pose2D(x, y, yaw)


class DiffDriveBase:
    """The true state of the base and the odometry its encoders would give.

    ``rng`` draws slip and encoder noise; pass a `numpy.random.Generator` of its own so other random
    sources (sensors, pets) do not change the trajectory.
    """

    def __init__(
        self,
        left: WheelMotor,
        right: WheelMotor,
        *,
        params: BaseParams | None = None,
        pose: Pose2D | None = None,
        rng: np.random.Generator,
        clearance: ClearanceFn | None = None,
    ) -> None:
        self.left = left
        self.right = right
        self.params = params or BaseParams()
        self.pose = pose or Pose2D()
        self.odom_pose = Pose2D()
        self.rng = rng
        self.clearance = clearance
        self.v_mps = 0.0
        self.w_radps = 0.0
        self.accel_mps2 = 0.0
        self.in_contact = False
        self.collisions: list[Collision] = []
        self.distance_m = 0.0
        self._slip = (0.0, 0.0)  # each wheel's slip (a fraction of its rim speed)

    def wheel_to_body(self, left_radps: float, right_radps: float) -> tuple[float, float]:
        """(v, ω) of the body for given wheel ground speeds."""
        r = self.params.wheel_radius_m
        return r * (right_radps + left_radps) / 2.0, r * (right_radps - left_radps) / self.params.track_m

    def step(self, t: float, dt_s: float) -> Collision | None:
        """Advance the wheels and the base by ``dt_s``; return the collision that began now, if any."""
        if dt_s <= 0:
            return None
        self.left.step(dt_s)
        self.right.step(dt_s)
        wl, wr = float(self.left.speed_radps), float(self.right.speed_radps)
        p = self.params
        # Odometry: what the encoders report (wheel speed plus measurement noise), integrated.
        # (Plain floats from here on: this runs 100 times a simulated second, and numpy's arithmetic on two numbers
        # costs several times a float's, for the same bits.)
        noise_l, noise_r = self.rng.normal(0.0, p.odom_noise_std, 2).tolist() if p.odom_noise_std else (0.0, 0.0)
        v_odom, w_odom = self.wheel_to_body(wl * (1 + noise_l), wr * (1 + noise_r))
        self.odom_pose = integrate_arc(self.odom_pose, v_odom, w_odom, dt_s)
        # Truth: rim speed minus slip, limited to the base's top speed. Slip is an Ornstein-Uhlenbeck process
        # (exact discretisation, stationary std ``slip_std``), so it varies smoothly, not from step to step.
        if p.slip_std:
            decay = math.exp(-dt_s / p.slip_time_constant_s)
            kick = p.slip_std * math.sqrt(1 - decay * decay)
            draw_l, draw_r = self.rng.normal(0.0, 1.0, 2).tolist()
            slip_l, slip_r = self._slip
            self._slip = (slip_l * decay + kick * draw_l, slip_r * decay + kick * draw_r)
        loss_l = min(abs(self._slip[0]), 0.9)
        loss_r = min(abs(self._slip[1]), 0.9)
        v, w = self.wheel_to_body(wl * (1 - loss_l), wr * (1 - loss_r))
        if abs(v) > p.max_speed_mps:
            scale = p.max_speed_mps / abs(v)
            v, w = v * scale, w * scale
        target = integrate_arc(self.pose, v, w, dt_s)
        event = None
        moved_fraction = 1.0
        if self.clearance is not None and (target.x_m, target.y_m) != (self.pose.x_m, self.pose.y_m):
            after = self.clearance(target.x_m, target.y_m)
            # Blocked when the step ends overlapping and goes deeper than where it started (so a base that
            # touches a wall can always back away from it).
            if after.clearance_m < 0 and after.clearance_m < self.clearance(self.pose.x_m, self.pose.y_m).clearance_m:
                # First contact: move up to the obstacle. Still pressing against it: stay (no sliding).
                moved_fraction = 0.0 if self.in_contact else self._touching_fraction(v, w, dt_s)
                stopped = integrate_arc(self.pose, v, w, dt_s * moved_fraction)
                target = Pose2D(stopped.x_m, stopped.y_m, target.yaw_rad)  # a round body still turns freely
                if not self.in_contact:
                    event = Collision(t, target, after.what, after.part)
                    self.collisions.append(event)
                self.in_contact = True
            else:
                self.in_contact = False
        v_eff = v * moved_fraction
        self.accel_mps2 = (v_eff - self.v_mps) / dt_s
        self.v_mps = v_eff
        self.w_radps = w
        self.distance_m += abs(v_eff) * dt_s
        self.pose = target
        return event

    def _touching_fraction(self, v: float, w: float, dt_s: float) -> float:
        """Largest fraction of the step (to 1/64) that keeps the footprint clear."""
        assert self.clearance is not None
        start = self.clearance(self.pose.x_m, self.pose.y_m).clearance_m
        lo, hi = 0.0, 1.0
        for _ in range(6):
            mid = (lo + hi) / 2
            p = integrate_arc(self.pose, v, w, dt_s * mid)
            c = self.clearance(p.x_m, p.y_m).clearance_m
            if c >= 0 or c >= start:
                lo = mid
            else:
                hi = mid
        return lo

    def teleport(self, pose: Pose2D) -> None:
        """Put the base somewhere else (kidnapping): the wheels keep their speeds, odometry does not notice."""
        self.pose = pose
        self.in_contact = False
        self.v_mps = self.w_radps = self.accel_mps2 = 0.0
