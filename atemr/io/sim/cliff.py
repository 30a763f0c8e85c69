"""The three IR cliff sensors (Sharp GP2Y0A41SK0F, 4–30 cm): floor distance, or out of range over a drop.

Each sensor looks straight down from under the base. Over normal floor it reads its mounting height
(plus a little noise); over a drop zone (resolved to the map's cells) the floor is ``depth_m`` lower,
and once that is beyond the sensor's 30 cm the reading is +inf ("nothing in range"), exactly what the
secondary core sends in CAN 0x151/0x152 when the robot is at the top of the stairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.io.sim.scene import Scene
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

    def __init__(self, params: CliffParams, scene: Scene, rng: np.random.Generator) -> None:
        self.params = params
        self.scene = scene
        self.rng = rng
        self._mount = (params.front_left_xy, params.front_right_xy, params.rear_xy)

    def sensor_points(self, pose: Pose2D) -> np.ndarray:
        """(3, 2) world positions of front-left, front-right, rear."""
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        mx = np.array([m[0] for m in self._mount])
        my = np.array([m[1] for m in self._mount])
        return np.stack([pose.x_m + c * mx - s * my, pose.y_m + s * mx + c * my], axis=1)

    def drop_depths(self, pose: Pose2D) -> list[float]:
        """How far below the floor each sensor's spot is (0 on the floor), to the map's cell size."""
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        return [self.scene.drop_depth_at(pose.x_m + c * mx - s * my, pose.y_m + s * mx + c * my)
                for mx, my in self._mount]

    def read(self, t: float, pose: Pose2D) -> CliffReadings:
        p = self.params
        noise = self.rng.normal(0.0, p.noise_std_m, 3) if p.noise_std_m else (0.0, 0.0, 0.0)
        out = []
        for depth, n in zip(self.drop_depths(pose), noise, strict=True):
            d = p.floor_distance_m + depth + float(n)
            out.append(math.inf if d > p.range_max_m else max(d, p.range_min_m))
        return CliffReadings(t, out[0], out[1], out[2])
