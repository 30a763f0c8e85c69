"""A simulated RPLIDAR A2M8: one revolution per call, all beams cast at once.

Range noise is Gaussian. As the RPLidar driver reports them (REP 117): a return beyond the maximum range is
+inf, closer than the minimum range -inf, and no return at all NaN: a beam that drops out (a small fraction:
a dark or glossy spot) or meets nothing within the device's own reach (``reach_m``, farther than the range
the robot uses). The scan is instantaneous: the robot's motion during a 0.1 s revolution is not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from atemr.errors import ConfigError
from atemr.io.sim.raycast import cast_circles
from atemr.io.sim.scene import Scene
from atemr.msgs import LaserScan, Pose2D


@dataclass(frozen=True)
class LidarParams:
    """The sensor; defaults are the RPLIDAR A2M8 of the thesis, mounted 10 cm ahead of the base centre and
    scanning the plane ``height_m`` above the floor (only what crosses that plane returns)."""

    beams: int = 360
    range_min_m: float = 0.15
    range_max_m: float = 8.0
    noise_std_m: float = 0.01
    dropout_prob: float = 0.005
    mount: Pose2D = field(default_factory=lambda: Pose2D(0.10, 0.0, 0.0))
    height_m: float = 0.2
    #: How far the device measures at all: 12 m for the A2M8 (its datasheet; 8 m for units up to revision R3).
    #: A return between ``range_max_m`` and this is reported beyond the range (+inf), none beyond it (NaN).
    reach_m: float = 12.0

    def __post_init__(self) -> None:
        if not 8 <= self.beams <= 8192:
            raise ConfigError(f"must be within 8..8192, got {self.beams}", path="lidar.beams")
        if not 0 <= self.range_min_m < self.range_max_m:
            raise ConfigError(f"need 0 <= range_min_m < range_max_m, got {self.range_min_m}, {self.range_max_m}",
                              path="lidar.range_min_m")
        if not (math.isfinite(self.height_m) and 0 < self.height_m < 3):
            raise ConfigError(f"must be within (0, 3) m, got {self.height_m!r}", path="lidar.height_m")
        if not (0 <= self.noise_std_m < 1 and 0 <= self.dropout_prob < 1):
            raise ConfigError("noise_std_m and dropout_prob must be within [0, 1)", path="lidar")
        if not (math.isfinite(self.reach_m) and self.reach_m >= self.range_max_m):
            raise ConfigError(f"must be finite and at least range_max_m ({self.range_max_m}), got {self.reach_m!r}",
                              path="lidar.reach_m")

    @property
    def angle_increment_rad(self) -> float:
        return 2.0 * math.pi / self.beams


class Lidar:
    """Produces `LaserScan`s from the scene; ``rng`` draws noise and dropouts."""

    def __init__(self, params: LidarParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        self.angles_rad = -math.pi + params.angle_increment_rad * np.arange(params.beams, dtype=np.float64)
        #: The last cast through what does not move: (its `Scene.view_key`, the ranges).
        self._static: tuple[tuple[float, float, float, object], np.ndarray] | None = None

    def true_ranges(self, pose: Pose2D, scene: Scene, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """Noise-free distance along each beam to the first wall, object or moving obstacle that crosses the scan
        plane (inf: none within ``reach_m``); a shoe under the plane and a table top above it are not seen.

        The walls and furniture are cast once for a `Scene.view_key` (a robot standing still), and only the people
        and pets are cast again."""
        p = self.params
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        sx = pose.x_m + c * p.mount.x_m - s * p.mount.y_m
        sy = pose.y_m + s * p.mount.x_m + c * p.mount.y_m
        key = scene.view_key(pose)
        kept = self._static
        if kept is not None and kept[0] == key:
            static = kept[1]
        else:
            gx, gy, gyaw = scene.to_grid_frame(sx, sy, pose.yaw_rad + p.mount.yaw_rad)
            static = scene.caster_at(p.height_m).cast((gx, gy), gyaw + self.angles_rad, p.reach_m).distance_m
            static.setflags(write=False)
            self._static = (key, static)
        if len(centres):
            world_angles = pose.yaw_rad + p.mount.yaw_rad + self.angles_rad
            d, _ = cast_circles((sx, sy), world_angles, centres, radii, p.reach_m)
            return np.minimum(static, d)
        return static.copy()

    def scan(self, t: float, pose: Pose2D, scene: Scene, centres: np.ndarray, radii: np.ndarray) -> LaserScan:
        """One revolution as seen from the true ``pose``."""
        p = self.params
        ranges = self.true_ranges(pose, scene, centres, radii)
        if p.noise_std_m:
            ranges = ranges + self.rng.normal(0.0, p.noise_std_m, ranges.shape)
        none = ~(ranges <= p.reach_m)  # nothing within the device's reach: no return
        if p.dropout_prob:
            none |= self.rng.random(ranges.shape) < p.dropout_prob
        ranges[ranges > p.range_max_m] = np.inf
        ranges[ranges < p.range_min_m] = -np.inf
        ranges[none] = np.nan
        return LaserScan(t, ranges, -math.pi, p.angle_increment_rad, p.range_min_m, p.range_max_m, p.mount)
