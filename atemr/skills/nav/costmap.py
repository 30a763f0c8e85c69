"""The navigation costmap: static layer + live obstacle layer + inflation (costmap_2d's layers, in numpy).

Cell costs use ROS costmap_2d's scale so maps and intuition carry over:

* ``LETHAL`` (254): an obstacle is in the cell;
* ``INSCRIBED`` (253): the robot's centre here puts its footprint (radius + padding) on an obstacle;
* 1..252: the inflation layer's cost, decaying exponentially with the distance beyond the inscribed radius,
  ``252 · exp(-cost_scaling · (d − inscribed))`` up to ``inflation_radius_m`` — the planners pay it, so
  paths keep away from walls where there is room, and still pass doorways where there is not;
* ``NO_INFORMATION`` (255): unknown space, when ``unknown`` is ``"unknown"`` (the planners may refuse it).

Layers. The static layer is the `OccupancyMap` (occupied cells lethal; unknown cells lethal, free or
unknown as configured). The obstacle layer holds what the lidar sees that the map does not: each scan
first *clears* the cells its beams pass through (ray tracing: a sample every half cell along each beam, in a
compiled loop, `_clear_beams`) and then *marks* the cells its returns end in, so a person who walked away
disappears and a new box appears.
A third layer, ``voxels``, holds what the depth camera sees between the floor and the robot's height
(`atemr.skills.nav.voxel_layer` marks and clears it); the lidar's clearing never touches it, since its beams
pass under a table top the camera sees. Both count as obstacles alike.
Inflation is a Euclidean distance transform (scipy.ndimage) to the nearest lethal cell of either layer;
the static layer's transform is computed once, the obstacle layer's only over the bounding box of its
marks, so a 10 Hz update stays cheap on big maps.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from atemr.domain.maps import OccupancyMap
from atemr.errors import NavigationError
from atemr.msgs import LaserScan, Pose2D

FREE_SPACE = 0
MAX_NON_OBSTACLE = 252
INSCRIBED = 253
LETHAL = 254
NO_INFORMATION = 255

UnknownPolicy = Literal["lethal", "free", "unknown"]


@dataclass(frozen=True)
class CostmapParams:
    """Geometry and layer settings (defaults: KAY's 0.25 m round footprint, the RPLIDAR's reach)."""

    robot_radius_m: float = 0.25
    #: Added to the radius for the inscribed zone: covers the grid's discretisation (up to a cell between a
    #: cell-centre distance and the true distance to an obstacle's edge) and odometry noise.
    footprint_padding_m: float = 0.05
    inflation_radius_m: float = 0.8
    cost_scaling: float = 6.0
    unknown: UnknownPolicy = "lethal"
    #: Extra room kept from what only the obstacle layer sees (people, pets, things not in the map): they
    #: count as this much closer. People walk up to a robot that hugs their line; the margin keeps it off
    #: their line and, when one comes closer anyway, puts the robot inside the inscribed zone, where the
    #: local planner allows only moves that open the gap (it steps aside or backs away). 0.1 m: people keep
    #: their own distance too; with 0.2 m a cat in the studio's 1.4 m bedroom passage closed it for good.
    obstacle_padding_m: float = 0.1
    #: Returns farther than this do not mark (noise grows with range); beams clear up to their return.
    obstacle_range_m: float = 4.0
    #: A return this close to a mapped obstacle (plus ``wall_match_per_m`` per metre of range: a heading error of
    #: a degree moves a far return by that much) is that obstacle, seen from a pose a few centimetres off. Marked,
    #: it would stay for good (the beams that could clear it end on it) and narrow doorways.
    wall_match_m: float = 0.08
    wall_match_per_m: float = 0.02
    raytrace_range_m: float = 6.0

    def __post_init__(self) -> None:
        for name in ("robot_radius_m", "inflation_radius_m", "cost_scaling", "obstacle_range_m", "raytrace_range_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise NavigationError(f"costmap: {name} must be a finite number > 0, got {value!r}")
        for name in ("footprint_padding_m", "obstacle_padding_m", "wall_match_m", "wall_match_per_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise NavigationError(f"costmap: {name} must be a finite number >= 0, got {value!r}")
        if self.unknown not in ("lethal", "free", "unknown"):
            raise NavigationError(f"costmap: unknown must be 'lethal', 'free' or 'unknown', got {self.unknown!r}")

    @property
    def inscribed_radius_m(self) -> float:
        return self.robot_radius_m + self.footprint_padding_m


def inflation_costs(distance_m: NDArray[np.floating], params: CostmapParams) -> NDArray[np.uint8]:
    """Cost of each cell from its distance to the nearest lethal cell (costmap_2d's inflation rule)."""
    d = np.asarray(distance_m, dtype=np.float64)
    r_in = params.inscribed_radius_m + 1e-6  # distances come as float32 multiples of the resolution
    with np.errstate(over="ignore"):
        decay = MAX_NON_OBSTACLE * np.exp(-params.cost_scaling * (d - r_in))
    cost = np.where(d <= params.inflation_radius_m, np.minimum(decay, MAX_NON_OBSTACLE), 0.0)
    cost = np.where(d <= r_in, INSCRIBED, np.floor(cost))
    cost = np.where(d <= 0.0, LETHAL, cost)
    return cost.astype(np.uint8)


class Costmap:
    """The layered costmap over one `OccupancyMap` (same grid, frame and resolution).

    ``cost`` (uint8, ROS scale) is what the planners read; ``distance_m`` (distance from each cell centre
    to the nearest lethal cell centre, less ``obstacle_padding_m`` for obstacle-layer cells) is what
    collision checks read. Both are recomputed lazily after
    the obstacle layer changed.
    """

    def __init__(self, occupancy: OccupancyMap, params: CostmapParams | None = None) -> None:
        self.map = occupancy
        self.params = params or CostmapParams()
        p = self.params
        self.resolution_m = occupancy.resolution_m
        self.shape = occupancy.data.shape
        unknown = occupancy.unknown
        lethal = occupancy.occupied.copy()
        if p.unknown == "lethal":
            lethal |= unknown
        self.static_lethal: NDArray[np.bool_] = lethal
        self.static_unknown: NDArray[np.bool_] = unknown & (p.unknown == "unknown")
        self._static_distance = self._distance(lethal)
        self.obstacles: NDArray[np.bool_] = np.zeros(self.shape, dtype=bool)
        #: Cells with something between the floor and the robot's height that the depth camera saw
        #: (`set_voxel_columns`); obstacles like the lidar's, but cleared only by the depth layer.
        self.voxels: NDArray[np.bool_] = np.zeros(self.shape, dtype=bool)
        #: How often `clear_obstacles` ran: the depth layer forgets its voxels when it changes.
        self.clears = 0
        #: Where moving obstacles are going (`set_predicted`), replaced at every scan; treated as obstacles.
        self.predicted: NDArray[np.bool_] = np.zeros(self.shape, dtype=bool)
        #: The last scan's returns the map does not explain, world (x, y) in beam order (for the tracker).
        self.unmapped_points: NDArray[np.float64] = np.zeros((0, 2))
        self.version = 0
        self._cache_version = -1
        self._cost: NDArray[np.uint8] = np.zeros(self.shape, dtype=np.uint8)
        self._dist: NDArray[np.float32] = self._static_distance
        self._hard: NDArray[np.float32] = self._static_distance
        self._static_cost: NDArray[np.uint8] | None = None
        self._inflate_cells = math.ceil((p.inflation_radius_m + p.obstacle_padding_m) / self.resolution_m) + 1
        load_compiled()

    # -- distances and costs -------------------------------------------------------------------------
    def _distance(self, lethal: NDArray[np.bool_]) -> NDArray[np.float32]:
        if not lethal.any():
            return np.full(lethal.shape, np.inf, dtype=np.float32)
        d = ndimage.distance_transform_edt(~lethal, sampling=self.resolution_m)
        return np.asarray(d, dtype=np.float32)

    def _window(self, layer: NDArray[np.bool_]) -> tuple[int, int, int, int] | None:
        """Bounding box of ``layer``'s cells grown by the inflation reach (rows r0:r1, cols c0:c1), or None."""
        if not layer.any():
            return None
        rows = np.flatnonzero(layer.any(axis=1))
        cols = np.flatnonzero(layer.any(axis=0))
        m = self._inflate_cells
        return (max(int(rows[0]) - m, 0), min(int(rows[-1]) + m + 1, self.shape[0]),
                max(int(cols[0]) - m, 0), min(int(cols[-1]) + m + 1, self.shape[1]))

    def _with_layer(self, base: NDArray[np.float32], layer: NDArray[np.bool_],
                    box: tuple[int, int, int, int] | None) -> NDArray[np.float32]:
        """``base`` lowered by the (padded) distance to the cells of ``layer``, computed over their box only."""
        if box is None:
            return base
        r0, r1, c0, c1 = box
        window = self._distance(layer[r0:r1, c0:c1]) - np.float32(self.params.obstacle_padding_m)
        out = base.copy()
        np.minimum(out[r0:r1, c0:c1], window, out=out[r0:r1, c0:c1])
        return out

    def _refresh(self) -> None:
        """Recompute distances and costs after a layer changed, only inside the layers' bounding box: outside
        it nothing differs from the static layer (a 10 Hz update stays cheap on a 1.7 M-cell warehouse)."""
        if self._cache_version == self.version:
            return
        if self._static_cost is None:
            self._static_cost = self._costs(self._static_distance, self.static_unknown)
            self._static_cost.setflags(write=False)
        seen = self.obstacles | self.voxels if self.voxels.any() else self.obstacles
        hard = self._with_layer(self._static_distance, seen, self._window(seen))
        layer = seen | self.predicted
        box = self._window(layer)
        dist = self._with_layer(hard, self.predicted, self._window(self.predicted)) if self.predicted.any() else hard
        cost = self._static_cost
        if box is not None:
            r0, r1, c0, c1 = box
            cost = cost.copy()
            cost[r0:r1, c0:c1] = self._costs(dist[r0:r1, c0:c1], self.static_unknown[r0:r1, c0:c1])
        self._hard = hard
        self._dist = dist
        self._cost = cost
        self._cache_version = self.version

    def _costs(self, dist: NDArray[np.float32], unknown: NDArray[np.bool_]) -> NDArray[np.uint8]:
        cost = inflation_costs(dist, self.params)
        cost[unknown & (cost < INSCRIBED)] = NO_INFORMATION
        return cost

    @property
    def cost(self) -> NDArray[np.uint8]:
        """Combined cost of every cell (static + obstacles, inflated)."""
        self._refresh()
        return self._cost

    @property
    def static_cost(self) -> NDArray[np.uint8]:
        """Cost from the map alone (what goal checks judge: a person standing on the goal is not a reason to
        refuse it; the planner then stops as near as it can within the tolerance)."""
        self._refresh()
        assert self._static_cost is not None
        return self._static_cost

    @property
    def distance_m(self) -> NDArray[np.float32]:
        """Distance from each cell centre to the nearest lethal cell centre, metres (inf: none)."""
        self._refresh()
        return self._dist

    # -- lookups in world coordinates ------------------------------------------------------------------
    def cells(self, x_m: NDArray[np.float64] | float, y_m: NDArray[np.float64] | float
              ) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
        """(row, col, inside) of world points; outside points get row/col clipped into the grid."""
        row, col = self.map.world_to_cell(x_m, y_m)
        rows, cols = self.shape
        if row.ndim == 0:  # one point (the robot's own cell, many times a tick): plain integers, no ufunc calls
            r, c = int(row), int(col)
            one: Any = (np.intp(min(max(r, 0), rows - 1)), np.intp(min(max(c, 0), cols - 1)),
                        np.bool_(0 <= r < rows and 0 <= c < cols))
            return one  # numpy scalars, as np.clip gives for one point
        return np.clip(row, 0, rows - 1), np.clip(col, 0, cols - 1), self.map.contains(row, col)

    def cost_at(self, x_m: NDArray[np.float64] | float, y_m: NDArray[np.float64] | float) -> NDArray[np.uint8]:
        """Cost at world points; ``LETHAL`` outside the grid (the robot must not leave the map)."""
        row, col, inside = self.cells(x_m, y_m)
        return np.where(inside, self.cost[row, col], LETHAL).astype(np.uint8)

    def distance_at(self, x_m: NDArray[np.float64] | float, y_m: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Clearance (m) at world points, predictions of moving obstacles included; 0 outside the grid."""
        row, col, inside = self.cells(x_m, y_m)
        return np.where(inside, self.distance_m[row, col], 0.0).astype(np.float64)

    def hard_distance_at(self, x_m: NDArray[np.float64] | float, y_m: NDArray[np.float64] | float
                         ) -> NDArray[np.float64]:
        """Clearance (m) from what is there now (map and obstacle layer, no predictions); 0 outside the grid."""
        self._refresh()
        row, col, inside = self.cells(x_m, y_m)
        return np.where(inside, self._hard[row, col], 0.0).astype(np.float64)

    @property
    def static_distance_m(self) -> NDArray[np.float32]:
        """Distance from each cell centre to the nearest lethal cell of the map alone, metres (inf: none)."""
        return self._static_distance

    def static_distance_at(self, x_m: NDArray[np.float64] | float, y_m: NDArray[np.float64] | float
                           ) -> NDArray[np.float64]:
        """Clearance (m) from the map alone; 0 outside the grid. A move that makes room for a person (who is
        in the obstacle layer too) must still never take the robot closer to a wall."""
        row, col, inside = self.cells(x_m, y_m)
        return np.where(inside, self._static_distance[row, col], 0.0).astype(np.float64)

    # -- obstacle layer ------------------------------------------------------------------------------
    def clear_obstacles(self) -> None:
        """Forget everything the obstacle layers hold (the first recovery behaviour)."""
        self.clears += 1
        if self.obstacles.any() or self.predicted.any() or self.voxels.any():
            self.obstacles[:] = False
            self.predicted[:] = False
            self.voxels[:] = False
            self.version += 1

    def set_voxel_columns(self, columns: NDArray[np.bool_]) -> None:
        """Replace the depth layer's cells (the columns of its voxel grid that hold an obstacle)."""
        if columns.shape != self.shape:
            raise NavigationError(f"costmap: voxel columns of shape {columns.shape}, the grid is {self.shape}")
        if not np.array_equal(columns, self.voxels):
            self.voxels = columns.copy()
            self.version += 1

    def set_predicted(self, points: NDArray[np.float64]) -> None:
        """Replace the predicted layer with the cells of ``points`` (world (x, y), e.g. from the tracker)."""
        new = np.zeros(self.shape, dtype=bool)
        if len(points):
            row, col, inside = self.cells(points[:, 0], points[:, 1])
            new[row[inside], col[inside]] = True
        if not np.array_equal(new, self.predicted):
            self.predicted = new
            self.version += 1

    def update_from_scan(self, scan: LaserScan, pose: Pose2D) -> int:
        """Clear along every valid beam, then mark each return's cell; returns how many cells are marked.

        ``pose`` is the base's pose in the map frame when the scan was taken. Returns beyond the max
        range (+inf, NaN, 0) neither mark nor clear: a dropped-out beam says nothing about what is there.
        ``-inf`` (closer than the minimum range) marks at the minimum range.
        """
        if not all(math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad)):
            raise NavigationError(f"costmap: robot pose must be finite, got {pose}")
        p = self.params
        ranges = np.asarray(scan.ranges_m, dtype=np.float64)
        too_close = np.isneginf(ranges)
        r = np.where(too_close, scan.range_min_m, ranges)
        valid = np.isfinite(r) & (r >= scan.range_min_m) & (r <= scan.range_max_m)
        valid &= r > 0
        if not valid.any():
            self.unmapped_points = np.zeros((0, 2))
            return int(self.obstacles.sum())
        r = r[valid]
        mount = scan.sensor_pose
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        sx = pose.x_m + c * mount.x_m - s * mount.y_m
        sy = pose.y_m + s * mount.x_m + c * mount.y_m
        ang = pose.yaw_rad + mount.yaw_rad + scan.angles_rad[valid]
        ux, uy = np.cos(ang), np.sin(ang)
        # Clearing: samples every half cell from the sensor to just before the return.
        reach = np.minimum(r, p.raytrace_range_m) - self.resolution_m
        before = self.obstacles.copy() if self.obstacles.any() else None
        if before is not None:  # nothing to clear in an empty layer
            self._clear((sx, sy), (ux, uy, reach))
        # Marking: the cells the returns end in, unless they are a mapped wall: a return within a cell and a
        # half (or ``wall_match_m`` and more with range) of a static obstacle is that obstacle seen with range
        # noise and pose error, and marking it would narrow every doorway by a cell.
        near = r <= p.obstacle_range_m
        mx, my = sx + ux[near] * r[near], sy + uy[near] * r[near]
        row, col, inside = self.cells(mx, my)
        row, col = row[inside], col[inside]
        match = np.maximum(1.5 * self.resolution_m, p.wall_match_m + p.wall_match_per_m * r[near][inside])
        new = self._static_distance[row, col] > match
        self.obstacles[row[new], col[new]] = True
        self.unmapped_points = np.column_stack([mx[inside][new], my[inside][new]])
        if before is None or not np.array_equal(before, self.obstacles):
            self.version += 1
        return int(self.obstacles.sum())

    def _clear(self, sensor: tuple[float, float],
               beams: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]) -> None:
        """Empty the obstacle cells that samples every half cell along each beam (unit direction ``ux, uy`` from
        ``sensor``, map frame) reach up to ``reach`` (`_clear_beams`)."""
        step = self.resolution_m / 2
        samples = int(max(beams[2].max(), 0.0) / step) + 1
        _clear_beams(self.obstacles, sensor, beams, (step, samples), self.grid_transform())

    def grid_transform(self) -> tuple[float, float, float, float, bool, float]:
        """What a compiled loop needs to find a world point's cell with `OccupancyMap.world_to_cell`'s arithmetic,
        in its order: the map origin's x and y, the cosine and sine of its yaw, whether it is rotated at all, and
        the resolution."""
        origin = self.map.origin
        c0, s0 = (math.cos(origin.yaw_rad), math.sin(origin.yaw_rad)) if origin.yaw_rad else (1.0, 0.0)
        return (origin.x_m, origin.y_m, c0, s0, bool(origin.yaw_rad), self.resolution_m)

    # -- views for the planners and the dashboard -------------------------------------------------------
    def traversable(self, *, allow_unknown: bool = False) -> NDArray[np.bool_]:
        """Cells the robot's centre may occupy: below ``INSCRIBED`` (and unknown ones if allowed)."""
        cost = self.cost
        ok = cost < INSCRIBED
        if allow_unknown:
            ok |= cost == NO_INFORMATION
        return ok


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) `_clear_beams` when the first costmap is built,
    not at the robot's first scan: the call has the argument types of `Costmap.update_from_scan`'s (a test checks
    that a running robot has one compiled version of each loop)."""
    one = np.ones(1)
    _clear_beams(np.zeros((1, 1), dtype=np.bool_), (0.0, 0.0), (one, one, one), (1.0, 1),
                 (0.0, 0.0, 1.0, 0.0, False, 1.0))


@njit(cache=True, nogil=True)
def _clear_beams(obstacles: NDArray[np.bool_], sensor: tuple[float, float],  # pragma: no cover  compiled by numba
                 beams: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
                 samples: tuple[float, int], grid: tuple[float, float, float, float, bool, float]) -> None:
    """Empty the cells of ``obstacles`` that samples ``0, step, 2 step, ...`` (at most ``count``) along each beam
    (unit direction ``ux, uy`` from ``sensor``, world frame) reach up to ``reach``. A sample's cell is
    `OccupancyMap.world_to_cell`'s arithmetic in the same order (``grid``: the map origin's x, y, the cosine and sine
    of its yaw, whether it is rotated, and the resolution), so the same cells as the numpy version this replaced,
    which built arrays of every beam's samples several times over."""
    sx, sy = sensor
    ux, uy, reach = beams
    step, count = samples
    ox, oy, c, s, rotated, resolution_m = grid
    h, w = obstacles.shape
    for b in range(ux.shape[0]):
        bx, by, end = ux[b], uy[b], reach[b]
        for k in range(count):
            t = k * step
            if not t <= end:
                break
            dx = (sx + bx * t) - ox
            dy = (sy + by * t) - oy
            if rotated:
                dx, dy = c * dx + s * dy, -s * dx + c * dy
            row = np.floor(dy / resolution_m)  # a float: NaN and huge values fall outside, as numpy's do
            col = np.floor(dx / resolution_m)
            if 0 <= row < h and 0 <= col < w:
                obstacles[int(row), int(col)] = False

