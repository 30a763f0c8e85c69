"""Ray casting against an occupancy grid and against circles (people, pets).

Grid rays use the exact cell traversal of Amanatides & Woo: the distances at which a ray crosses vertical
grid lines are ``t_k = (x_k - x0) / dx``, and at each crossing it enters the cell just beyond that line; the
same for horizontal lines. The first blocked cell entered across either family is the hit, so the distance
is exact (to float precision) for any angle, with no step size to tune.

The walk is a compiled loop (`numba`): a ray costs a few nanoseconds a cell, where the numpy traversal it
replaced paid numpy's per-call overhead dozens of times a chunk of crossings. It computes every crossing with
the same expressions in the same order, so a seed gives the same distances and cells, to the bit, as before
(``tests/io/sim/test_raycast.py`` compares the two). One thing may differ: which face a ray is said to enter
(``GridHits.side``, the camera's shading of a wall) when it crosses a grid corner exactly and both faces there
are blocked. The walk names the vertical line's face (side 0); the numpy traversal named the one it happened to
examine first in its chunks of crossings. The simulated robot's poses are never that exact, so no seeded run
meets it.

All distances are in metres; the grid frame is the map's (see `atemr.domain.maps.OccupancyMap`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


@dataclass(frozen=True)
class GridHits:
    """Where each ray stopped: distance (inf: nothing within range), the hit cell and which face.

    ``side`` is 0 when the ray entered the cell through a vertical grid line (an x-face, a wall running
    along y), 1 through a horizontal line, -1 for no hit and 2 when the ray starts inside a blocked cell.
    """

    distance_m: FloatArray
    row: IntArray
    col: IntArray
    side: NDArray[np.int8]


class GridCaster:
    """Casts rays through one fixed grid; build once per grid, cast many times.

    It keeps the grid padded with a border of empty cells, so a walk needs no bounds test inside the grid.
    """

    def __init__(self, blocked: NDArray[np.bool_], resolution_m: float) -> None:
        self.shape = blocked.shape
        self.resolution_m = float(resolution_m)
        height, width = blocked.shape
        padded = np.zeros((height + 2, width + 2), dtype=bool)
        padded[1:-1, 1:-1] = blocked
        self._blocked = blocked
        #: The grid the rays are cast through (read-only).
        self.blocked = blocked
        self._flat = padded.ravel()
        self._stride = width + 2
        load_compiled()

    @functools.cached_property
    def clearance_cells(self) -> FloatArray:
        """Distance from each cell's centre to the nearest blocked cell's centre, in cells (inf: none): the scene
        places things in the open with it. Computed when first asked (only the scene's whole-grid caster is)."""
        from scipy import ndimage

        blocked = self.blocked
        out: FloatArray = (ndimage.distance_transform_edt(~blocked).astype(np.float64) if blocked.any()
                           else np.full(blocked.shape, np.inf))
        return out

    def cast(self, origin_xy: tuple[float, float], angles_rad: FloatArray,
             max_range_m: float | FloatArray) -> GridHits:
        """One ray per angle from ``origin_xy`` (grid frame, metres from the lower-left corner), up to
        ``max_range_m`` (one range, or one per ray: the camera stops its furniture rays at the wall, so they
        end as soon as nothing in front of it can be left); cells outside the grid are empty."""
        res = self.resolution_m
        angles = np.asarray(angles_rad, dtype=np.float64)
        n = angles.shape[0]
        height, width = self.shape
        gx0 = origin_xy[0] / res
        gy0 = origin_xy[1] / res
        r0, c0 = math.floor(gy0), math.floor(gx0)
        if 0 <= r0 < height and 0 <= c0 < width and self._blocked[r0, c0]:
            return GridHits(np.zeros(n), np.full(n, r0, dtype=np.intp), np.full(n, c0, dtype=np.intp),
                            np.full(n, 2, dtype=np.int8))
        # The trigonometry stays in numpy (its vectorised sin and cos), so the compiled walk sees the same
        # directions, to the bit, as the numpy traversal it replaced.
        dx = np.cos(angles)
        dy = np.sin(angles)
        # Axis-parallel rays never cross lines of that axis: a tiny component pushes those crossings past range.
        dx = np.where(np.abs(dx) < 1e-12, np.copysign(1e-12, dx), dx)
        dy = np.where(np.abs(dy) < 1e-12, np.copysign(1e-12, dy), dy)
        t_max = np.empty(n)
        t_max[:] = np.asarray(max_range_m, dtype=np.float64) / res
        dist = np.empty(n)
        hit_row = np.empty(n, dtype=np.intp)
        hit_col = np.empty(n, dtype=np.intp)
        side = np.empty(n, dtype=np.int8)
        _walk_rays(self._flat, self._stride, width, height, gx0, gy0, dx, dy, np.abs(1.0 / dx), np.abs(1.0 / dy),
                   t_max, res, dist, hit_row, hit_col, side)
        return GridHits(dist, hit_row, hit_col, side)


@njit(cache=True, nogil=True, inline="always")
def _blocked(flat: NDArray[np.bool_], stride: int, height: int, row: int, col: int
             ) -> bool:  # pragma: no cover  compiled by numba
    """Whether padded cell (row, col) blocks (``stride`` is the padded width); off the padded grid is its empty
    border (a ray from outside)."""
    return bool(flat[min(max(row, 0), height + 1) * stride + min(max(col, 0), stride - 1)])


@njit(cache=True, nogil=True)
def _walk_rays(flat: NDArray[np.bool_], stride: int, width: int, height: int,  # noqa: PLR0917  one compiled loop
               gx0: float, gy0: float, dx: FloatArray, dy: FloatArray, inv_dx: FloatArray, inv_dy: FloatArray,
               t_max: FloatArray, res: float, dist: FloatArray, hit_row: IntArray, hit_col: IntArray,
               side: NDArray[np.int8]) -> None:  # pragma: no cover  compiled by numba; tested through GridCaster
    """Walk each ray's crossings in order of distance (in cells) and write where it stopped (`_first_hit`).

    ``flat`` is the padded grid (``height + 2`` rows of ``stride = width + 2``), the origin ``(gx0, gy0)``
    is in cells, and a ray with no blocked cell within ``t_max`` gets distance inf, cell -1 and side -1.
    """
    inside = 0.0 <= gx0 <= width and 0.0 <= gy0 <= height
    for i in range(dx.shape[0]):
        ddx = dx[i]
        ddy = dy[i]
        pos_x = ddx > 0
        pos_y = ddy > 0
        if inside:
            # Nothing beyond the grid's edge can stop a ray that started inside it.
            tx_exit = abs((float(width) if pos_x else 0.0) - gx0) * inv_dx[i]
            ty_exit = abs((float(height) if pos_y else 0.0) - gy0) * inv_dy[i]
            lim = min(t_max[i], tx_exit, ty_exit)
        else:
            # From outside: stop once the ray has passed the grid's far side on either axis (no hit there).
            far_x = ((float(width) if pos_x else 0.0) - gx0) / ddx
            far_y = ((float(height) if pos_y else 0.0) - gy0) / ddy
            lim = min(t_max[i], far_x + 1.0, far_y + 1.0)
        # A NaN angle or range hits nothing (it is not walked: it would never end).
        walk = lim >= 0.0 and not (math.isnan(ddx) or math.isnan(ddy))
        t, row, col, face = (_first_hit((flat, stride, height), (gx0, gy0), (ddx, ddy, inv_dx[i], inv_dy[i]), lim)
                             if walk else (0.0, 0, 0, -1))
        found = face >= 0
        dist[i] = t * res if found else math.inf
        hit_row[i] = row - 1 if found else -1
        hit_col[i] = col - 1 if found else -1
        side[i] = face


@njit(cache=True, nogil=True)
def _first_hit(grid: tuple[NDArray[np.bool_], int, int], origin: tuple[float, float],
               ray: tuple[float, float, float, float], lim: float
               ) -> tuple[float, int, int, int]:  # pragma: no cover  compiled by numba
    """The first blocked cell one ray enters within ``lim`` (cells): its distance in cells, its padded row and
    column, and the face it entered through (0: a vertical grid line, 1: a horizontal one, -1: none).

    ``grid``: the padded grid, its stride and height; ``ray``: its direction and the absolute inverses of both
    components. Where the two families cross at the same distance, the vertical line (an x-face) is looked at
    first. The cell across the other axis is found from where the crossing lands, nudged 1e-9 of a cell along
    the ray, so a crossing exactly on a grid corner enters the cell the ray heads into.
    """
    flat, stride, height = grid
    gx0, gy0 = origin
    ddx, ddy, ix, iy = ray
    pos_x = ddx > 0
    pos_y = ddy > 0
    step_x = 1.0 if pos_x else -1.0
    step_y = 1.0 if pos_y else -1.0
    off_x = 1 if pos_x else 0
    off_y = 1 if pos_y else 0
    nudge_x = math.copysign(1e-9, ddx)
    nudge_y = math.copysign(1e-9, ddy)
    line_x = math.floor(gx0) + (1.0 if pos_x else 0.0)
    line_y = math.floor(gy0) + (1.0 if pos_y else 0.0)
    tx = abs(line_x - gx0) * ix
    ty = abs(line_y - gy0) * iy
    while True:
        if tx <= ty:
            if tx > lim:
                return 0.0, 0, 0, -1
            col = int(line_x) + off_x
            row = math.floor(gy0 + tx * ddy + nudge_y) + 1
            if _blocked(flat, stride, height, row, col):
                return tx, row, col, 0
            line_x += step_x
            tx = abs(line_x - gx0) * ix
        else:
            if ty > lim:
                return 0.0, 0, 0, -1
            row = int(line_y) + off_y
            col = math.floor(gx0 + ty * ddx + nudge_x) + 1
            if _blocked(flat, stride, height, row, col):
                return ty, row, col, 1
            line_y += step_y
            ty = abs(line_y - gy0) * iy


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) the walk when the first caster is built, not
    at the robot's first scan: the call has the argument types of `GridCaster.cast`'s, so it is the one the ticks
    use (a test checks that a running robot has one compiled version of each loop)."""
    flat = np.zeros(9, dtype=np.bool_)  # one empty cell and its border
    out = (np.empty(1), np.empty(1, dtype=np.intp), np.empty(1, dtype=np.intp), np.empty(1, dtype=np.int8))
    _walk_rays(flat, 3, 1, 1, 0.5, 0.5, np.ones(1), np.full(1, 1e-12), np.ones(1), np.full(1, 1e12), np.ones(1), 1.0,
               *out)
    _circle_hits(np.ones(1), np.zeros(1), np.ones(1), np.ones(1), np.ones(1), 1.0, out[0], out[1])


def cast_grid(
    blocked: NDArray[np.bool_],
    resolution_m: float,
    origin_xy: tuple[float, float],
    angles_rad: FloatArray,
    max_range_m: float,
) -> GridHits:
    """Cast one ray per angle from ``origin_xy`` (grid frame, metres from the grid's lower-left corner).

    ``blocked[row, col]`` marks cells that stop a ray (row 0 at the bottom). Cells outside the grid are
    empty. Returns the distance to the first blocked cell along each ray, up to ``max_range_m``. For
    repeated casts against the same grid, build a `GridCaster` once.
    """
    return GridCaster(blocked, resolution_m).cast(origin_xy, angles_rad, max_range_m)


def cast_circles(
    origin_xy: tuple[float, float],
    angles_rad: FloatArray,
    centres_xy: FloatArray,
    radii_m: FloatArray,
    max_range_m: float = math.inf,
) -> tuple[FloatArray, IntArray]:
    """Distance along each ray to the nearest circle, and that circle's index (-1: none within range).

    ``centres_xy`` is (N, 2) in the same frame as the origin. A ray starting inside a circle has
    distance 0 to it. Ties go to the circle listed first.
    """
    angles = np.asarray(angles_rad, dtype=np.float64)
    centres = np.asarray(centres_xy, dtype=np.float64).reshape(-1, 2)
    radii = np.asarray(radii_m, dtype=np.float64).reshape(-1)
    if centres.shape[0] == 0:
        return np.full(angles.shape[0], np.inf), np.full(angles.shape[0], -1, dtype=np.intp)
    best = np.empty(angles.shape[0])
    which = np.empty(angles.shape[0], dtype=np.intp)
    # The trigonometry stays in numpy (see `GridCaster.cast`); a ray's tests of every circle are one compiled loop.
    _circle_hits(np.cos(angles), np.sin(angles), origin_xy[0] - centres[:, 0], origin_xy[1] - centres[:, 1],
                 radii ** 2, float(max_range_m), best, which)
    return best, which


@njit(cache=True, nogil=True)
def _circle_hits(dx: FloatArray, dy: FloatArray, fx: FloatArray, fy: FloatArray,  # noqa: PLR0917  one compiled loop
                 r2: FloatArray, max_range_m: float, best: FloatArray,
                 which: IntArray) -> None:  # pragma: no cover  compiled by numba; tested through cast_circles
    """For each ray (direction ``(dx, dy)``), the nearest circle it meets within ``max_range_m``: the quadratic
    ``|f + t d|^2 = r^2`` with ``f`` the origin less the centre, in the order and the expressions the numpy
    version used (`benchmarks/numpy_baselines.py`'s `numpy_cast_circles`), so the distances have the same bits."""
    for i in range(dx.shape[0]):
        nearest = math.inf
        found = -1
        for k in range(fx.shape[0]):
            b = fx[k] * dx[i] + fy[k] * dy[i]
            c = fx[k] * fx[k] + fy[k] * fy[k] - r2[k]
            disc = b * b - c
            root = math.sqrt(max(disc, 0.0))
            t_near = -b - root
            t_far = -b + root
            t = t_near if t_near >= 0 else (0.0 if t_far >= 0 else math.inf)
            if not (disc >= 0 and t <= max_range_m):
                t = math.inf
            if t < nearest:  # the first of equal distances, as argmin
                nearest = t
                found = k
        best[i] = nearest
        which[i] = found
