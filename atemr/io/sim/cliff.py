"""The three IR cliff sensors (Sharp GP2Y0A41SK0F, 4–30 cm): floor distance, or out of range over a drop.

Each sensor looks straight down from under the base. Over normal floor it reads its mounting height
(plus a little noise); over a drop zone the floor is ``depth_m`` lower, and once that is beyond the
sensor's 30 cm the reading is +inf ("nothing in range"), exactly what the secondary core sends in CAN
0x151/0x152 when the robot is at the top of the stairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.io.sim.world import DropZone
from atemr.msgs import CliffReadings, Pose2D


@dataclass(frozen=True)
class CliffParams:
    """Where the sensors sit in the base frame (x forward, y left) and what they read."""

    front_left_xy: tuple[float, float] = (0.20, 0.14)
    front_right_xy: tuple[float, float] = (0.20, -0.14)
    rear_xy: tuple[float, float] = (-0.22, 0.0)
    floor_distance_m: float = 0.06
    range_min_m: float = 0.04
    range_max_m: float = 0.30
    noise_std_m: float = 0.002

    def __post_init__(self) -> None:
        if not self.range_min_m <= self.floor_distance_m <= self.range_max_m:
            raise ConfigError(
                f"floor distance {self.floor_distance_m} m must be within the sensor range "
                f"[{self.range_min_m}, {self.range_max_m}] m", path="cliff.floor_distance_m")
        if not (math.isfinite(self.noise_std_m) and self.noise_std_m >= 0):
            raise ConfigError(f"must be >= 0, got {self.noise_std_m}", path="cliff.noise_std_m")


class CliffSensors:
    """Reads the three sensors at a pose against the world's drop zones."""

    def __init__(self, params: CliffParams, zones: tuple[DropZone, ...], rng: np.random.Generator) -> None:
        self.params = params
        self.zones = zones
        self.rng = rng
        self._mount = np.array([params.front_left_xy, params.front_right_xy, params.rear_xy], dtype=np.float64)

    def sensor_points(self, pose: Pose2D) -> np.ndarray:
        """(3, 2) world positions of front-left, front-right, rear."""
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        mx, my = self._mount[:, 0], self._mount[:, 1]
        return np.stack([pose.x_m + c * mx - s * my, pose.y_m + s * mx + c * my], axis=1)

    def drop_depths(self, pose: Pose2D) -> np.ndarray:
        """How far below the floor each sensor's spot is (0 on the floor; the deepest zone wins)."""
        pts = self.sensor_points(pose)
        depth = np.zeros(3)
        for zone in self.zones:
            depth = np.where(zone.contains(pts[:, 0], pts[:, 1]), np.maximum(depth, zone.depth_m), depth)
        return depth

    def read(self, t: float, pose: Pose2D) -> CliffReadings:
        p = self.params
        d = p.floor_distance_m + self.drop_depths(pose)
        if p.noise_std_m:
            d = d + self.rng.normal(0.0, p.noise_std_m, 3)
        d = np.where(d > p.range_max_m, np.inf, np.maximum(d, p.range_min_m))
        return CliffReadings(t, float(d[0]), float(d[1]), float(d[2]))
