"""The occupancy grid every part of the robot shares: `OccupancyMap` and its cell values.

Skills (localization, navigation, SLAM) compute on it, the map store and the simulator read and write it,
the dashboard draws it. It lives here, in the pure domain layer, so that a skill can take a map without
importing the simulator or any file format: reading and writing maps in the ROS map_server format is
`atemr.io.sim.maps` (`load_map`, `save_map`), which builds this type.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.msgs import Pose2D

#: Cell values, as in a ROS OccupancyGrid (1..99 are probabilities in ``scale`` mode).
OCCUPIED = 100
FREE = 0
UNKNOWN = -1


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy grid with its place in the world.

    ``data[row, col]`` holds ROS OccupancyGrid values (100 occupied, 0 free, -1 unknown, 1..99 a
    probability in ``scale`` mode). Row 0 is the *bottom* of the map (lowest y), as in ROS, so cell
    ``(row, col)`` covers ``x in origin.x + [col, col+1) * resolution`` (before the origin's yaw).
    """

    data: NDArray[np.int8]
    resolution_m: float
    origin: Pose2D = field(default_factory=Pose2D)
    occupied_thresh: float = 0.65
    free_thresh: float = 0.25
    name: str = "map"

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.size == 0:
            raise ConfigError(f"map '{self.name}': grid must be a non-empty 2-D array, got shape {self.data.shape}")
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise ConfigError(f"map '{self.name}': resolution must be > 0 m, got {self.resolution_m}")
        self.data.setflags(write=False)

    # -- shape ---------------------------------------------------------------------------------
    @property
    def height(self) -> int:
        """Rows (cells along y)."""
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        """Columns (cells along x)."""
        return int(self.data.shape[1])

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height in metres."""
        return self.width * self.resolution_m, self.height * self.resolution_m

    # -- masks ---------------------------------------------------------------------------------
    @property
    def occupied(self) -> NDArray[np.bool_]:
        """Cells at least as likely occupied as ``occupied_thresh`` (all 100s in a trinary map)."""
        return self.data >= min(OCCUPIED, round(self.occupied_thresh * 100))

    @property
    def free(self) -> NDArray[np.bool_]:
        """Cells known to be free."""
        return (self.data >= 0) & (self.data <= round(self.free_thresh * 100))

    @property
    def unknown(self) -> NDArray[np.bool_]:
        return self.data < 0

    # -- transforms ----------------------------------------------------------------------------
    def world_to_grid(self, x_m: Any, y_m: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World coordinates → continuous grid coordinates (gx along columns, gy along rows), in cells."""
        dx = np.asarray(x_m, dtype=np.float64) - self.origin.x_m
        dy = np.asarray(y_m, dtype=np.float64) - self.origin.y_m
        if self.origin.yaw_rad:
            c, s = math.cos(self.origin.yaw_rad), math.sin(self.origin.yaw_rad)
            dx, dy = c * dx + s * dy, -s * dx + c * dy
        return dx / self.resolution_m, dy / self.resolution_m

    def world_to_cell(self, x_m: Any, y_m: Any) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """World coordinates → (row, col) indices; may be outside the grid (see `contains`)."""
        gx, gy = self.world_to_grid(x_m, y_m)
        return np.floor(gy).astype(np.intp), np.floor(gx).astype(np.intp)

    def cell_to_world(self, row: Any, col: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(row, col) → world coordinates of the cell centre."""
        gx = (np.asarray(col, dtype=np.float64) + 0.5) * self.resolution_m
        gy = (np.asarray(row, dtype=np.float64) + 0.5) * self.resolution_m
        if self.origin.yaw_rad:
            c, s = math.cos(self.origin.yaw_rad), math.sin(self.origin.yaw_rad)
            gx, gy = c * gx - s * gy, s * gx + c * gy
        return gx + self.origin.x_m, gy + self.origin.y_m

    def contains(self, row: Any, col: Any) -> NDArray[np.bool_]:
        """Whether (row, col) indices lie inside the grid."""
        r, c = np.asarray(row), np.asarray(col)
        return (r >= 0) & (r < self.height) & (c >= 0) & (c < self.width)

    def value_at(self, x_m: float, y_m: float) -> int:
        """The cell value at a world point; unknown (-1) outside the grid."""
        row, col = self.world_to_cell(x_m, y_m)
        if not self.contains(row, col):
            return UNKNOWN
        return int(self.data[int(row), int(col)])

    def replace(self, data: NDArray[np.int8]) -> OccupancyMap:
        """The same map (resolution, origin, thresholds) with another grid of the same shape."""
        if data.shape != self.data.shape:
            raise ConfigError(f"map '{self.name}': new grid shape {data.shape} differs from {self.data.shape}")
        return OccupancyMap(
            np.array(data, dtype=np.int8), self.resolution_m, self.origin, self.occupied_thresh, self.free_thresh,
            self.name,
        )
