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

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
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


#: Above this many table look-ups, `LikelihoodField.crossings` walks segments by sphere tracing instead of
#: sampling them every half cell.
DENSE_LOOKUPS = 200_000


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
        off_map_log_p = math.log(p.z_hit * norm * math.exp(-0.5 * (p.max_dist_m / p.sigma_hit_m) ** 2) + rand)
        # The tables carry a border of one cell holding the off-map value: a point is clipped into it, so a
        # look-up needs no test for "inside the map".
        self._log_p = np.pad(log_p, 1, constant_values=off_map_log_p).ravel()
        self._dist_flat = np.pad(dist, 1, constant_values=p.max_dist_m).ravel()
        self._stride = grid.width + 2
        o = grid.origin
        self._origin = np.array([o.x_m, o.y_m, o.yaw_rad])
        self.log_p_max = float(self._log_p.max())
        load_compiled()

    # -- look-ups ----------------------------------------------------------------------------------
    def _flat_index(self, gx: NDArray[np.floating[Any]], gy: NDArray[np.floating[Any]]) -> NDArray[np.intp]:
        """Flat index into the bordered tables of grid-frame metric points; off-map (and NaN) points land
        on the border."""
        inv = 1.0 / self.map.resolution_m
        with np.errstate(invalid="ignore", over="ignore"):  # fmax/fmin take the number over a NaN: the border
            col = np.floor(gx * inv)
            np.fmax(col, -1.0, out=col)
            np.fmin(col, float(self.map.width), out=col)
            row = np.floor(gy * inv)
            np.fmax(row, -1.0, out=row)
            np.fmin(row, float(self.map.height), out=row)
        # float32 holds integers exactly up to 2**24: flat indices of a map of up to 16 M cells
        flat = row.astype(np.intp)
        flat += 1
        flat *= self._stride
        flat += col.astype(np.intp)
        flat += 1
        return flat

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
        """Cell index of every point under every pose: ``(N, M)``.

        The ``N × M`` arithmetic runs in float32 (a tenth of a millimetre at 1 km from the origin, far below a
        cell) in a compiled loop (`_cells_into`), the pose transforms in float64."""
        with np.errstate(invalid="ignore", over="ignore"):  # absurd poses land off the map, never warn
            frames = _float32_frames(self._to_grid_frame(np.asarray(poses, dtype=np.float64).reshape(-1, 3)))
            px = np.ascontiguousarray(points[:, 0], dtype=np.float32)
            py = np.ascontiguousarray(points[:, 1], dtype=np.float32)
        out = np.empty((frames[0].shape[0], px.shape[0]), dtype=np.intp)
        _cells_into(frames, (px, py), np.float32(1.0 / self.map.resolution_m), (self.map.height, self.map.width), out)
        return out

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

    def distances(self, poses: FloatArray, points: FloatArray) -> FloatArray:
        """Distance (m) from every base-frame point, under every pose ``(N, 3)``, to the nearest occupied cell:
        ``(N, M)``; 0 in an occupied cell, ``max_dist_m`` off the map."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        n = np.asarray(poses).reshape(-1, 3).shape[0]
        if pts.shape[0] == 0:
            return np.zeros((n, 0))
        return self._dist_flat[self._indices(poses, pts)]

    def crossings(self, poses: FloatArray, start_xy: tuple[float, float], points: FloatArray,
                  stop_short_m: float) -> NDArray[np.bool_]:
        """Whether the segment from ``start_xy`` to each base-frame point, ending ``stop_short_m`` before the
        point, enters an occupied cell, under every pose: ``(N, M)``.

        Few segments are sampled every half cell (the samples are the same base-frame points under every
        pose); many are walked by sphere tracing, which costs a few steps per segment in open space instead
        of one per half cell. Both walks are compiled loops that stop at a segment's first occupied cell, with
        the arithmetic of the numpy versions they replaced (float32 for the samples, as `distances`), so they
        answer the same.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        n = np.asarray(poses).reshape(-1, 3).shape[0]
        crossed = np.zeros((n, pts.shape[0]), dtype=bool)
        if pts.shape[0] == 0 or n == 0:
            return crossed
        start = np.asarray(start_xy, dtype=np.float64).reshape(1, 2)
        ray = pts - start
        length = np.hypot(ray[:, 0], ray[:, 1])
        reach = np.maximum(length - stop_short_m, 0.0)
        samples = max(2, math.ceil(float(reach.max()) / (0.5 * self.map.resolution_m)) + 1)
        with np.errstate(invalid="ignore", over="ignore"):  # absurd poses land off the map, never warn
            g = self._to_grid_frame(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
        h, w = self.map.height, self.map.width
        if n * pts.shape[0] * samples > DENSE_LOOKUPS:
            with np.errstate(invalid="ignore", over="ignore"):
                c, s = np.cos(g[:, 2])[:, None], np.sin(g[:, 2])[:, None]
                x0 = (g[:, 0:1] + c * start[0, 0] - s * start[0, 1]) + np.zeros((1, pts.shape[0]))
                y0 = (g[:, 1:2] + s * start[0, 0] + c * start[0, 1]) + np.zeros((1, pts.shape[0]))
                unit = np.divide(ray, length[:, None], out=np.zeros_like(ray), where=length[:, None] > 0)
                ux, uy = c * unit[:, 0] - s * unit[:, 1], s * unit[:, 0] + c * unit[:, 1]
            res = self.map.resolution_m
            _traced(self._dist_flat, (h, w), 1.0 / res, (res * math.sqrt(2.0), 0.5 * res),
                    (x0, y0, ux, uy), reach, crossed)
            return crossed
        scale = np.divide(reach, length, out=np.zeros_like(length), where=length > 0)
        frac = np.linspace(0.0, 1.0, samples)
        # A sample's cell that far from every occupied one has free cells all round it: the samples within that
        # distance, less a cell's diagonal and a margin for float32's rounding, are not looked at.
        slack = self.map.resolution_m * (math.sqrt(2.0) + 0.05)
        _sampled(self._dist_flat, (h, w), np.float32(1.0 / self.map.resolution_m), _float32_frames(g),
                 (start[0, 0], start[0, 1]), (ray, scale, frac), slack, crossed)
        return crossed

    def agreement(self, poses: FloatArray, points: FloatArray) -> FloatArray:
        """Fraction of end points within ``agreement_tolerance_m`` of an obstacle, per pose (0 for no points).

        Cheap, and blind to what lies between the sensor and the point: a scan seen through a wall still
        scores. Decisions about the pose use `atemr.skills.localization.map_agreement` instead."""
        d = self.distances(poses, points)
        if d.shape[1] == 0:
            return np.zeros(d.shape[0])
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


F32 = NDArray[np.float32]
#: (cos, sin, x, y) of grid-frame poses in float32.
Float32Frames = tuple[F32, F32, F32, F32]


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) the field's loops (both walks of `crossings`,
    the cells of `_indices`) when the first field is built, not in the middle of the robot's first scan: the calls
    have the argument types of the methods' (a test checks that a running robot has one compiled version of each)."""
    field = np.zeros(9)  # one occupied cell and its border
    crossed = np.zeros((1, 1), dtype=np.bool_)
    one = np.ones((1, 1))
    _traced(field, (1, 1), 1.0, (1.0, 0.5), (one, one, one, one), np.ones(1), crossed)
    ray = np.ones((1, 2))
    f32 = np.ones(1, dtype=np.float32)
    _sampled(field, (1, 1), np.float32(1.0), (f32, f32, f32, f32), (ray[0, 0], ray[0, 1]),
             (ray, np.ones(1), np.ones(2)), 1.5, crossed)
    _cells_into((f32, f32, f32, f32), (f32, f32), np.float32(1.0), (1, 1), np.empty((1, 1), dtype=np.intp))


def _float32_frames(grid_poses: FloatArray) -> Float32Frames:
    """(cos, sin, x, y) of grid-frame poses ``(N, 3)`` in float32: what every point is turned and moved by."""
    with np.errstate(invalid="ignore", over="ignore"):  # absurd poses land off the map, never warn
        return (np.cos(grid_poses[:, 2]).astype(np.float32), np.sin(grid_poses[:, 2]).astype(np.float32),
                grid_poses[:, 0].astype(np.float32), grid_poses[:, 1].astype(np.float32))


@njit(cache=True, nogil=True, inline="always")
def _cell(shape: tuple[int, int], inv: float | np.float32, x: float | np.float32,
          y: float | np.float32) -> int:  # pragma: no cover  compiled by numba
    """The bordered tables' flat index of a grid-frame point (`LikelihoodField._flat_index` for one point, in the
    point's own precision: ``inv`` is float32 for float32 points); off the map and NaN land on the border."""
    height, width = shape
    col = np.floor(x * inv)  # a float (math.floor's integer has no NaN or infinity)
    row = np.floor(y * inv)
    col = -1.0 if not col >= -1.0 else min(col, float(width))
    row = -1.0 if not row >= -1.0 else min(row, float(height))
    return (int(row) + 1) * (width + 2) + int(col) + 1


@njit(cache=True, nogil=True, inline="always")
def _occupied(dist_flat: FloatArray, shape: tuple[int, int], inv: float | np.float32, x: float | np.float32,
              y: float | np.float32) -> float:  # pragma: no cover  compiled by numba
    """The clipped distance at a grid-frame point (`_cell`)."""
    return float(dist_flat[_cell(shape, inv, x, y)])


@njit(cache=True, nogil=True)
def _cells_into(frames: Float32Frames, points: tuple[F32, F32], inv: np.float32, shape: tuple[int, int],
                out: NDArray[np.intp]) -> None:  # pragma: no cover  compiled by numba
    """The flat index of every point under every pose, ``out[i, j]``: each point turned and moved into pose ``i``'s
    grid frame in float32, as `LikelihoodField._indices` did with numpy."""
    c, s, gx0, gy0 = frames
    px, py = points
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            gx = c[i] * px[j] - s[i] * py[j] + gx0[i]
            gy = s[i] * px[j] + c[i] * py[j] + gy0[i]
            out[i, j] = _cell(shape, inv, gx, gy)


@njit(cache=True, nogil=True)
def _traced(dist_flat: FloatArray, shape: tuple[int, int], inv: float, steps: tuple[float, float],  # noqa: PLR0917  one compiled loop
            rays: tuple[FloatArray, FloatArray, FloatArray, FloatArray], reach: FloatArray,
            crossed: NDArray[np.bool_]) -> None:  # pragma: no cover  compiled by numba
    """Sphere tracing of every segment (pose ``i``, point ``j``) from ``(x0, y0)`` along ``(ux, uy)`` up to
    ``reach[j]``: from a point ``d`` from the nearest occupied cell centre, nothing occupied lies within
    ``d − margin`` (``steps``: the margin, a cell's diagonal, and the least step, half a cell).

    A walk ends a cell past where its line leaves the map for good: nothing beyond can be occupied, so the answer
    is the one the whole walk would give, and a segment a million kilometres long (or one from a NaN pose) does
    not walk for ever."""
    x0, y0, ux, uy = rays
    margin, least = steps
    height, width = shape
    size_x, size_y, cell = width / inv, height / inv, 2.0 * least
    for i in range(x0.shape[0]):
        for j in range(x0.shape[1]):
            beyond = min(_leaves(x0[i, j], ux[i, j], size_x), _leaves(y0[i, j], uy[i, j], size_y)) + cell
            end = reach[j]
            if not beyond >= end:  # the map's far edge comes first, or NaN: no walk beyond it
                end = 0.0 if math.isnan(beyond) else max(beyond, 0.0)
            t = 0.0
            while True:
                d = _occupied(dist_flat, shape, inv, x0[i, j] + ux[i, j] * t, y0[i, j] + uy[i, j] * t)
                if d <= 0.0:
                    crossed[i, j] = True
                    break
                if not t < end:  # one last look exactly at the end, then stop
                    break
                t = min(t + max(d - margin, least), end)


@njit(cache=True, nogil=True, inline="always")
def _leaves(start: float, step: float, size: float) -> float:  # pragma: no cover  compiled by numba
    """How far along a line ``start + t · step`` (metres) its coordinate leaves ``[0, size]`` for good (negative:
    behind it already; -inf: never inside)."""
    if step > 0.0:
        return (size - start) / step
    if step < 0.0:
        return -start / step
    return np.inf if 0.0 <= start <= size else -np.inf


@njit(cache=True, nogil=True)
def _sampled(dist_flat: FloatArray, shape: tuple[int, int], inv: np.float32,  # noqa: PLR0917  one compiled loop
             frames: Float32Frames,
             start: tuple[float, float], segments: tuple[FloatArray, FloatArray, FloatArray], slack_m: float,
             crossed: NDArray[np.bool_]) -> None:  # pragma: no cover  compiled by numba
    """Every segment sampled at the fractions ``frac`` of its reach (``segments``: each point's ray from
    ``start``, its reach over its length, and the evenly spaced fractions), each sample turned into every pose's
    grid frame in float32; a segment is crossed at its first sample in an occupied cell.

    The answer is that of looking at every sample, but a sample in a cell ``d`` from the nearest occupied cell
    centre vouches for the samples after it within ``d - slack_m``: two points that far apart are in cells whose
    centres are at most that plus a cell's diagonal apart, and the distance table changes no faster than the
    distance between centres (a clipped distance too). Border cells (off the map) vouch for nothing: they hold
    ``max_dist_m`` whatever the map's edge holds."""
    c, s, gx0, gy0 = frames
    ray, scale, frac = segments
    height, width = shape
    last = frac.shape[0] - 1
    for j in range(ray.shape[0]):
        # the samples' spacing along the segment, rounded up by a millionth: a skip never reaches too far
        spacing = scale[j] * math.hypot(ray[j, 0], ray[j, 1]) / max(last, 1) * (1.0 + 1e-6)
        for i in range(c.shape[0]):
            k = 0
            while k <= last:
                along = scale[j] * frac[k]
                px = np.float32(start[0] + along * ray[j, 0])
                py = np.float32(start[1] + along * ray[j, 1])
                gx = c[i] * px - s[i] * py + gx0[i]
                gy = s[i] * px + c[i] * py + gy0[i]
                index = _cell(shape, inv, gx, gy)
                d = dist_flat[index]
                if d <= 0.0:
                    crossed[i, j] = True
                    break
                free = d - slack_m
                row, col = divmod(index, width + 2)
                if 0.0 < spacing < free and 0 < row <= height and 0 < col <= width:
                    k += int(free / spacing)
                k += 1


__all__ = ["FieldParams", "LikelihoodField"]
