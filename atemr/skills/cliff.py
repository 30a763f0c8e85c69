"""Cliff stop: the three IR floor sensors veto any motion that carries a sensor further over a drop.

KAY has three Sharp IR sensors under the base (thesis 3.2, 3.6.3; front left, front right, rear centre,
range 4–30 cm) looking at the floor. Over the floor they read their mounting height (about 6 cm); at
the top of the stairs the floor falls away and the reading jumps past ``floor_distance_m +
tolerance_m`` or out of range (+inf). A NaN reading is a sensor fault and is treated as a drop too:
the base must not drive blind towards stairs.

"Motion towards the drop" is decided per sensor from the velocity of the sensor's own mounting point,
``(v − ω·y_s, ω·x_s)`` in the base frame: a front sensor over a drop vetoes any twist that moves it
forward, the rear sensor any twist that moves it backward. So the operator can still back away from
the stairs or turn the dropped side away from them, and a vetoed twist stops the base at once (the
pipeline also drops the speed ramp's state to zero, bypassing the ramp like an emergency).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from atemr.errors import ConfigError
from atemr.msgs import ZERO_TWIST, CliffReadings, Twist

SENSORS = ("front_left", "front_right", "rear")


@dataclass(frozen=True)
class CliffGeometry:
    """Sensor mountings (base frame, metres) and what counts as a drop.

    Defaults match the simulator's sensors (`atemr.io.sim.cliff.CliffParams`): 0.20 m ahead and
    ±0.14 m aside at the front, 0.22 m behind at the rear, 6 cm above the floor.
    """

    front_left_xy: tuple[float, float] = (0.20, 0.14)
    front_right_xy: tuple[float, float] = (0.20, -0.14)
    rear_xy: tuple[float, float] = (-0.22, 0.0)
    floor_distance_m: float = 0.06
    #: Extra distance tolerated before a reading is a drop: noise, carpets, door sills (a few cm).
    tolerance_m: float = 0.04

    def __post_init__(self) -> None:
        if not (self.floor_distance_m > 0 and self.tolerance_m >= 0):
            raise ConfigError(
                f"cliff: need floor_distance_m > 0 and tolerance_m >= 0, got {self.floor_distance_m}, "
                f"{self.tolerance_m}"
            )
        if self.front_left_xy[0] <= 0 or self.front_right_xy[0] <= 0 or self.rear_xy[0] >= 0:
            raise ConfigError("cliff: front sensors must sit ahead of the axle (x > 0) and the rear one behind")

    @property
    def drop_threshold_m(self) -> float:
        """A reading above this (or not a number) means a drop under that sensor."""
        return self.floor_distance_m + self.tolerance_m


def drops(readings: CliffReadings, geometry: CliffGeometry) -> NDArray[np.bool_]:
    """(front_left, front_right, rear): which sensors see a drop. NaN and +inf are drops."""
    d = np.array([readings.front_left_m, readings.front_right_m, readings.rear_m], dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return ~(d <= geometry.drop_threshold_m)


def blocked(
    linear_mps: ArrayLike, angular_radps: ArrayLike, dropped: ArrayLike, geometry: CliffGeometry
) -> NDArray[np.bool_]:
    """Whether each twist moves a sensor that sees a drop towards it (arrays broadcast over twists).

    ``dropped`` is the three booleans of `drops`. A twist that keeps every dropped sensor still (or
    moves it away) is allowed.
    """
    v = np.asarray(linear_mps, dtype=np.float64)[..., None]
    w = np.asarray(angular_radps, dtype=np.float64)[..., None]
    ys = np.array([geometry.front_left_xy[1], geometry.front_right_xy[1], geometry.rear_xy[1]])
    forward = v - w * ys  # x-velocity of each sensor's mounting point
    facing = np.array([1.0, 1.0, -1.0])  # front sensors guard forward motion, the rear one backward
    towards = forward * facing > 1e-9
    return np.any(towards & np.asarray(dropped, dtype=bool), axis=-1)


@dataclass(frozen=True)
class CliffVerdict:
    """The twist after the cliff check, which sensors see a drop, and whether the twist was vetoed.

    ``blind``: the readings were missing or stale, so every sensor counts as seeing a drop. A carer is then told
    that the floor sensors went quiet, not that stairs are under the robot."""

    twist: Twist
    drops: tuple[bool, bool, bool]
    stopped: bool
    blind: bool = False


class CliffStop:
    """Applies `blocked` to one twist per tick; stale or missing readings count as drops.

    ``max_age_s``: readings older than this (the secondary core went silent) are not trusted, so the
    base behaves as if every sensor saw a drop and does not move. ``require_readings=False`` is for a
    base without cliff sensors: missing or stale readings then veto nothing.
    """

    def __init__(
        self, geometry: CliffGeometry | None = None, max_age_s: float = 0.5, *, require_readings: bool = True
    ) -> None:
        if not (max_age_s > 0 and math.isfinite(max_age_s)):
            raise ConfigError(f"cliff: max_age_s must be positive, got {max_age_s!r}")
        self.geometry = geometry or CliffGeometry()
        self.max_age_s = max_age_s
        self.require_readings = require_readings

    def check(self, now: float, twist: Twist, readings: CliffReadings | None) -> CliffVerdict:
        """``twist``, or zero when it carries a sensor towards a drop."""
        # the same rule as `drops` and `blocked`, in plain floats: one twist per tick, where numpy's
        # per-call overhead would cost more than the arithmetic (tests check both agree)
        g = self.geometry
        blind = readings is None or not (now - readings.t <= self.max_age_s)
        if readings is None or blind:
            flags = (self.require_readings,) * 3
        else:
            limit = g.drop_threshold_m
            fl, fr, rear = readings.front_left_m, readings.front_right_m, readings.rear_m
            flags = (not fl <= limit, not fr <= limit, not rear <= limit)
        v, w = twist.linear_mps, twist.angular_radps
        stop = (
            (flags[0] and v - w * g.front_left_xy[1] > 1e-9)
            or (flags[1] and v - w * g.front_right_xy[1] > 1e-9)
            or (flags[2] and -(v - w * g.rear_xy[1]) > 1e-9)
        )
        return CliffVerdict(ZERO_TWIST if stop else twist, (flags[0], flags[1], flags[2]), stop,
                            blind and self.require_readings)


__all__ = ["SENSORS", "CliffGeometry", "CliffStop", "CliffVerdict", "blocked", "drops"]
