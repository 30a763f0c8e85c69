"""Recovery behaviours, tried in order when the robot is stuck or has no path (move_base's idea):

1. ``clear costmap`` — forget the obstacle layer (stale marks: a person who has left, a ghost from noise);
2. ``rotate in place`` — one full turn, so the lidar re-marks and re-clears all around;
3. ``back off`` — reverse a short distance, only as far as the costmap behind stays clear;
4. ``replan`` — stand still a moment (a person in a doorway may step aside), then plan again.

After each one the navigator plans again; when all are used up without progress it fails with the reason
of the last failure (no path, stuck). Each behaviour is a small state machine stepped with the time and
pose it is given: it returns the twist to command and whether it has finished.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from atemr.errors import NavigationError
from atemr.msgs import ZERO_TWIST, Pose2D, Twist
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.local_planner import wrap

RecoveryKind = Literal["clear costmap", "rotate in place", "back off", "replan"]
DEFAULT_SEQUENCE: tuple[RecoveryKind, ...] = ("clear costmap", "rotate in place", "back off", "replan")


@dataclass(frozen=True)
class RecoveryParams:
    """How each behaviour moves; the sequence is the order they are tried in."""

    sequence: tuple[RecoveryKind, ...] = DEFAULT_SEQUENCE
    rotate_speed_radps: float = 0.8
    backoff_speed_mps: float = 0.15
    backoff_distance_m: float = 0.3
    replan_wait_s: float = 3.0

    def __post_init__(self) -> None:
        for kind in self.sequence:
            if kind not in DEFAULT_SEQUENCE:
                raise NavigationError(f"recovery: unknown behaviour {kind!r}; known: {', '.join(DEFAULT_SEQUENCE)}")
        for name in ("rotate_speed_radps", "backoff_speed_mps", "backoff_distance_m", "replan_wait_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise NavigationError(f"recovery: {name} must be a finite number > 0, got {value!r}")


class RecoveryBehaviour:
    """One running recovery; `step` until it says it is done."""

    def __init__(self, kind: RecoveryKind, params: RecoveryParams, now: float, pose: Pose2D) -> None:
        self.kind = kind
        self.params = params
        self.t0 = now
        self.start_pose = pose
        self._last_yaw = pose.yaw_rad
        self._turned = 0.0
        p = params
        limits = {
            "clear costmap": 0.0,
            "rotate in place": 2 * math.pi / p.rotate_speed_radps * 1.5 + 1.0,
            "back off": p.backoff_distance_m / p.backoff_speed_mps * 2.0 + 1.0,
            "replan": p.replan_wait_s,
        }
        self.time_limit_s = limits[kind]

    def step(self, now: float, pose: Pose2D, costmap: Costmap) -> tuple[Twist, bool]:
        """The twist for this tick, and whether the behaviour has finished (then the twist is zero)."""
        p = self.params
        elapsed = now - self.t0
        if self.kind == "clear costmap":
            costmap.clear_obstacles()
            return ZERO_TWIST, True
        if elapsed >= self.time_limit_s:
            return ZERO_TWIST, True
        if self.kind == "rotate in place":
            self._turned += abs(float(wrap(pose.yaw_rad - self._last_yaw)))
            self._last_yaw = pose.yaw_rad
            if self._turned >= 2 * math.pi - 0.15:
                return ZERO_TWIST, True
            return Twist(0.0, p.rotate_speed_radps), False
        if self.kind == "back off":
            moved = pose.distance_to(self.start_pose)
            if moved >= p.backoff_distance_m or not self._rear_clear(pose, costmap):
                return ZERO_TWIST, True
            return Twist(-p.backoff_speed_mps, 0.0), False
        return ZERO_TWIST, False  # replan: stand still until the wait is over

    @staticmethod
    def _rear_clear(pose: Pose2D, costmap: Costmap) -> bool:
        """Whether reversing 10 cm keeps the footprint out of the inscribed zone (or no closer than now)."""
        d = np.array([0.05, 0.10])
        xs = pose.x_m - d * math.cos(pose.yaw_rad)
        ys = pose.y_m - d * math.sin(pose.yaw_rad)
        here = float(costmap.hard_distance_at(pose.x_m, pose.y_m))
        limit = min(costmap.params.inscribed_radius_m, here)
        return bool((costmap.hard_distance_at(xs, ys) >= limit).all())
