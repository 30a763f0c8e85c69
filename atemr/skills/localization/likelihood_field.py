"""The likelihood-field measurement model (Thrun, Burgard & Fox, Probabilistic Robotics §6.4).

A beam's end point ``z`` is scored by the distance ``d`` from it to the nearest occupied cell:
``p(z) = z_hit · N(d; 0, σ_hit) + z_rand / range_max``. The distance to the nearest obstacle is a
property of the map alone, so it is computed once with a Euclidean distance transform
(`scipy.ndimage.distance_transform_edt`), and so is ``log p`` for every cell: scoring N poses × M
points is then one rigid transform and one table look-up per point, with no search at run time.
End points outside the map score as "far from everything" (``max_dist_m``), which is what a return
through an open door into unmapped space deserves.

`agreement` is the fraction of points that land within ``tolerance_m`` of an obstacle: a number an
operator understands ("72 % of the scan matches the map") and the covariance monitor's second test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError
from atemr.skills.localization.geometry import FloatArray


@dataclass(frozen=True)
class FieldParams:
    """Measurement model constants (AMCL's ``laser_*`` parameters)."""

    sigma_hit_m: float = 0.1
    z_hit: float = 0.9
    z_rand: float = 0.1
    range_max_m: float = 8.0
    #: Distances are clipped here: beyond it every point is equally "not near the map".
    max_dist_m: float = 2.0
    #: A point counts as agreeing with the map within this distance of an occupied cell.
    agreement_tolerance_m: float = 0.15

    def __post_init__(self) -> None:
        for name in ("sigma_hit_m", "range_max_m", "max_dist_m", "agreement_tolerance_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.{name}")
        if not (0 <= self.z_hit <= 1 and 0 < self.z_rand <= 1):
            raise ConfigError(f"need 0 <= z_hit <= 1 and 0 < z_rand <= 1, got {self.z_hit}, {self.z_rand}",
                              path="localization.z_hit")


class LikelihoodField:
    """Distance and log-likelihood tables of one map, and vectorised scoring of poses against them.

    Poses are given in the map's world frame; internally they are moved into the grid frame once (the
    map origin may be rotated), so each point needs only a scale and a floor to find its cell.
    """

    def __init__(self, grid: OccupancyMap, params: FieldParams | None = None) -> None:
        self.map = grid
        self.params = p = params or FieldParams()
        occupied = grid.occupied
        if not occupied.any():
            raise ConfigError(f"map '{grid.name}' has no occupied cell: nothing to localize against")
        res = grid.resolution_m
        dist = ndimage.distance_transform_edt(~occupied).astype(np.float64) * res
        np.minimum(dist, p.max_dist_m, out=dist)
        #: Distance (m) from each cell centre to the nearest occupied cell centre, clipped at ``max_dist_m``.
        self.distance_m: NDArray[np.float64] = dist
        norm = 1.0 / (math.sqrt(2.0 * math.pi) * p.sigma_hit_m)
        rand = p.z_rand / p.range_max_m
        log_p = np.log(p.z_hit * norm * np.exp(-0.5 * (dist / p.sigma_hit_m) ** 2) + rand)
        #: ``log p(z)`` of an end point in each cell; one extra cell at the end holds the off-map value.
        self._log_p = np.append(log_p.ravel(), math.log(p.z_hit * norm * math.exp(-0.5 * (p.max_dist_m / p.sigma_hit_m)
                                                                                   ** 2) + rand))
        self._dist_flat = np.append(dist.ravel(), p.max_dist_m)
        self._off_map = grid.height * grid.width
        o = grid.origin
        self._origin = np.array([o.x_m, o.y_m, o.yaw_rad])
        self.log_p_max = float(self._log_p.max())

    # -- look-ups ----------------------------------------------------------------------------------
    def _flat_index(self, gx: FloatArray, gy: FloatArray) -> NDArray[np.intp]:
        """Flat table index of grid-frame metric points; off-map (and NaN) points → the extra cell."""
        res = self.map.resolution_m
        with np.errstate(invalid="ignore", over="ignore"):
            col = np.floor(gx / res)
            row = np.floor(gy / res)
            inside = (col >= 0) & (col < self.map.width) & (row >= 0) & (row < self.map.height)
        flat = np.where(inside, np.where(inside, row, 0) * self.map.width + np.where(inside, col, 0), self._off_map)
        return flat.astype(np.intp)

    def _to_grid_frame(self, poses: FloatArray) -> FloatArray:
        """Poses ``(N, 3)`` in the world → relative to the map's origin (lower-left corner, its axes)."""
        ox, oy, oth = self._origin
        if oth == 0.0:
            out = poses.copy()
            out[:, 0] -= ox
            out[:, 1] -= oy
            return out
        c, s = math.cos(oth), math.sin(oth)
        dx, dy = poses[:, 0] - ox, poses[:, 1] - oy
        return np.column_stack([c * dx + s * dy, -s * dx + c * dy, poses[:, 2] - oth])

    def _indices(self, poses: FloatArray, points: FloatArray) -> NDArray[np.intp]:
        """Cell index of every point under every pose: ``(N, M)``."""
        with np.errstate(invalid="ignore", over="ignore"):
            g = self._to_grid_frame(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
            c = np.cos(g[:, 2])[:, None]
            s = np.sin(g[:, 2])[:, None]
        px, py = points[:, 0][None, :], points[:, 1][None, :]
        with np.errstate(invalid="ignore", over="ignore"):  # absurd poses land off the map, never warn
            gx = g[:, 0:1] + c * px - s * py
            gy = g[:, 1:2] + s * px + c * py
        return self._flat_index(gx, gy)

    def distance(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Distance to the nearest obstacle at world points (``max_dist_m`` off the map)."""
        gx, gy = self.map.world_to_grid(x_m, y_m)
        res = self.map.resolution_m
        return self._dist_flat[self._flat_index(gx * res, gy * res)]

    # -- scoring -----------------------------------------------------------------------------------
    def log_likelihood(self, poses: FloatArray, points: FloatArray) -> FloatArray:
        """``Σ_beams log p(z | pose)`` for each of ``N`` poses ``(N, 3)``; ``points`` ``(M, 2)`` in the base frame."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if pts.shape[0] == 0:
            return np.zeros(np.asarray(poses).reshape(-1, 3).shape[0])
        return self._log_p[self._indices(poses, pts)].sum(axis=1)

    def agreement(self, poses: FloatArray, points: FloatArray) -> FloatArray:
        """Fraction of points within ``agreement_tolerance_m`` of an obstacle, per pose (0 for no points)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        n = np.asarray(poses).reshape(-1, 3).shape[0]
        if pts.shape[0] == 0:
            return np.zeros(n)
        d = self._dist_flat[self._indices(poses, pts)]
        return (d <= self.params.agreement_tolerance_m).mean(axis=1)

    def obstacle_points(self) -> FloatArray:
        """World coordinates of the occupied cells that border non-occupied space (the map's surfaces).

        What a lidar can actually hit: interior cells of a thick wall are never seen, so matching
        against them would only pull scans into walls.
        """
        occ = self.map.occupied
        interior = ndimage.binary_erosion(occ, structure=np.ones((3, 3), bool), border_value=1)
        rows, cols = np.nonzero(occ & ~interior)
        x, y = self.map.cell_to_world(rows, cols)
        return np.column_stack([x, y])


__all__ = ["FieldParams", "LikelihoodField"]
