"""Vectorised ray casting against an occupancy grid and against circles (people, pets).

Grid rays use the exact cell traversal of Amanatides & Woo, computed for all rays at once: the
distances at which a ray crosses vertical grid lines are ``t_k = (x_k - x0) / dx``, and at each crossing
it enters the cell just beyond that line; the same for horizontal lines. The first blocked cell entered
across either family is the hit, so the distance is exact (to float precision) for any angle, with no
step size to tune. Work is done in chunks of crossings, dropping the rays that have already hit, so a
room where most beams stop within a few metres costs far less than the full 8 m.

All distances are in metres; the grid frame is the map's (see `atemr.io.sim.maps.OccupancyMap`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Crossings processed per chunk (per axis); small enough that rays stopping early are dropped soon.
CHUNK = 24


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


def cast_grid(
    blocked: NDArray[np.bool_],
    resolution_m: float,
    origin_xy: tuple[float, float],
    angles_rad: FloatArray,
    max_range_m: float,
) -> GridHits:
    """Cast one ray per angle from ``origin_xy`` (grid frame, metres from the grid's lower-left corner).

    ``blocked[row, col]`` marks cells that stop a ray (row 0 at the bottom). Cells outside the grid are
    empty. Returns the distance to the first blocked cell along each ray, up to ``max_range_m``.
    """
    angles = np.asarray(angles_rad, dtype=np.float64)
    n = angles.shape[0]
    height, width = blocked.shape
    gx0 = origin_xy[0] / resolution_m
    gy0 = origin_xy[1] / resolution_m
    t_max = max_range_m / resolution_m

    dist = np.full(n, np.inf)
    hit_row = np.full(n, -1, dtype=np.intp)
    hit_col = np.full(n, -1, dtype=np.intp)
    side = np.full(n, -1, dtype=np.int8)

    r0, c0 = math.floor(gy0), math.floor(gx0)
    if 0 <= r0 < height and 0 <= c0 < width and blocked[r0, c0]:
        return GridHits(np.zeros(n), np.full(n, r0, dtype=np.intp), np.full(n, c0, dtype=np.intp),
                        np.full(n, 2, dtype=np.int8))

    # A one-cell empty border lets every index be clipped into range instead of masked.
    padded = np.zeros((height + 2, width + 2), dtype=bool)
    padded[1:-1, 1:-1] = blocked
    flat_grid = padded.ravel()
    stride = width + 2

    dx = np.cos(angles)
    dy = np.sin(angles)
    # Axis-parallel rays never cross lines of that axis: a tiny component pushes those crossings past range.
    dx = np.where(np.abs(dx) < 1e-12, np.copysign(1e-12, dx), dx)
    dy = np.where(np.abs(dy) < 1e-12, np.copysign(1e-12, dy), dy)
    inv_dx = np.abs(1.0 / dx)
    inv_dy = np.abs(1.0 / dy)
    fx, fy = math.floor(gx0), math.floor(gy0)
    # Per ray: first vertical/horizontal line crossed, the step between lines, and the offset from a line
    # index to the cell entered through it (the line itself going up/right, the one before going down/left).
    x_first = np.where(dx > 0, fx + 1.0, float(fx))
    y_first = np.where(dy > 0, fy + 1.0, float(fy))
    x_step = np.where(dx > 0, 1.0, -1.0)
    y_step = np.where(dy > 0, 1.0, -1.0)
    x_off = np.where(dx > 0, 1, 0)  # +1 for the padding border
    # Where a crossing lands exactly on a grid corner, the cell entered is the one the ray is heading into.
    nudge_x = np.copysign(1e-9, dx)
    nudge_y = np.copysign(1e-9, dy)
    y_off = np.where(dy > 0, 1, 0)

    # Where each ray leaves the grid (when it starts inside it): nothing beyond can stop it.
    t_lim = np.full(n, t_max)
    if 0.0 <= gx0 <= width and 0.0 <= gy0 <= height:
        tx_exit = np.abs(np.where(dx > 0, float(width), 0.0) - gx0) * inv_dx
        ty_exit = np.abs(np.where(dy > 0, float(height), 0.0) - gy0) * inv_dy
        t_lim = np.minimum(t_lim, np.minimum(tx_exit, ty_exit))

    cand_t = np.full(n, np.inf)
    cand_flat = np.zeros(n, dtype=np.intp)
    alive = np.arange(n)
    n_cross = math.ceil(t_max) + 2
    for k0 in range(0, n_cross, CHUNK):
        if alive.size == 0:
            break
        k = np.arange(k0, min(k0 + CHUNK, n_cross), dtype=np.float64)
        a = alive
        ar = np.arange(a.size)
        lim = t_lim[a, None]
        # Crossings of vertical lines (x-faces).
        line = x_first[a, None] + x_step[a, None] * k
        tx = np.abs(line - gx0) * inv_dx[a, None]
        cx = np.clip(line.astype(np.intp) + x_off[a, None], 0, width + 1)
        rx = np.clip(np.floor(gy0 + tx * dy[a, None] + nudge_y[a, None]).astype(np.intp) + 1, 0, height + 1)
        fx_idx = rx * stride + cx
        tx_hit = np.where(flat_grid[fx_idx] & (tx <= lim), tx, np.inf)
        jx = tx_hit.argmin(axis=1)
        best_tx = tx_hit[ar, jx]
        # Crossings of horizontal lines (y-faces).
        line = y_first[a, None] + y_step[a, None] * k
        ty = np.abs(line - gy0) * inv_dy[a, None]
        ry = np.clip(line.astype(np.intp) + y_off[a, None], 0, height + 1)
        cy = np.clip(np.floor(gx0 + ty * dx[a, None] + nudge_x[a, None]).astype(np.intp) + 1, 0, width + 1)
        fy_idx = ry * stride + cy
        ty_hit = np.where(flat_grid[fy_idx] & (ty <= lim), ty, np.inf)
        jy = ty_hit.argmin(axis=1)
        best_ty = ty_hit[ar, jy]

        # The nearest hit of this chunk, kept as a candidate: x- and y-crossings of one chunk cover different
        # distances, so a hit is final only once both axes have been examined up to it.
        use_y = best_ty < best_tx
        best_t = np.where(use_y, best_ty, best_tx)
        better = best_t < cand_t[a]
        sel = a[better]
        cand_t[sel] = best_t[better]
        cand_flat[sel] = np.where(use_y, fy_idx[ar, jy], fx_idx[ar, jx])[better]
        side[sel] = use_y[better].astype(np.int8)
        covered = np.minimum(tx[:, -1], ty[:, -1])
        past = (tx[:, -1] >= lim[:, 0]) & (ty[:, -1] >= lim[:, 0])
        done = (cand_t[a] <= covered) | past
        alive = a[~done]
    got = np.nonzero(np.isfinite(cand_t))[0]
    dist[got] = cand_t[got] * resolution_m
    hit_row[got] = cand_flat[got] // stride - 1
    hit_col[got] = cand_flat[got] % stride - 1
    return GridHits(dist, hit_row, hit_col, side)


def cast_circles(
    origin_xy: tuple[float, float],
    angles_rad: FloatArray,
    centres_xy: FloatArray,
    radii_m: FloatArray,
    max_range_m: float = math.inf,
) -> tuple[FloatArray, IntArray]:
    """Distance along each ray to the nearest circle, and that circle's index (-1: none within range).

    ``centres_xy`` is (N, 2) in the same frame as the origin. A ray starting inside a circle has
    distance 0 to it.
    """
    angles = np.asarray(angles_rad, dtype=np.float64)
    centres = np.asarray(centres_xy, dtype=np.float64).reshape(-1, 2)
    radii = np.asarray(radii_m, dtype=np.float64).reshape(-1)
    if centres.shape[0] == 0:
        return np.full(angles.shape[0], np.inf), np.full(angles.shape[0], -1, dtype=np.intp)
    dx = np.cos(angles)[:, None]
    dy = np.sin(angles)[:, None]
    fx = (origin_xy[0] - centres[:, 0])[None, :]
    fy = (origin_xy[1] - centres[:, 1])[None, :]
    b = fx * dx + fy * dy
    c = fx * fx + fy * fy - radii[None, :] ** 2
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    t_near = -b - root
    t_far = -b + root
    t = np.where(t_near >= 0, t_near, np.where(t_far >= 0, 0.0, np.inf))
    t = np.where((disc >= 0) & (t <= max_range_m), t, np.inf)
    which = t.argmin(axis=1)
    best = t[np.arange(t.shape[0]), which]
    which = np.where(np.isfinite(best), which, -1)
    return best, which.astype(np.intp)
