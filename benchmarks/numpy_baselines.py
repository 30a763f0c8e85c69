"""The numpy versions of the loops issue 22 compiled, as they were, as the baselines of the compiled ones.

* `NumpyGridCaster`: the simulator's grid ray traversal that `atemr.io.sim.raycast.GridCaster` replaced;
* `NumpyLikelihoodField`: the likelihood field with the numpy `crossings` (map agreement's "does this beam pass
  through a wall") and ``_indices`` (the cell of every point under every pose, which AMCL's weights and every
  distance look up) that `atemr.skills.localization.likelihood_field` replaced;
* `NumpyMarkLayer`: the depth camera's voxel layer with the numpy ``_mark`` (which voxels a frame's points fill)
  that `atemr.skills.nav.voxel_layer` replaced;
* `NumpyShapesDepthCamera`: the simulated depth camera with the numpy slab and cylinder tests of furniture,
  people and pets that `atemr.io.sim.depth` replaced;
* `numpy_edge_weights`: the global planner's edge weights (every cell's eight steps, reduced by A*'s heuristic)
  that `atemr.skills.nav.global_planner.edge_weights` replaced;
* `NumpyClearingCostmap`: the costmap whose obstacle layer clears a scan's beams with numpy, every beam's samples at
  once, which `atemr.skills.nav.costmap`'s ``_clear_beams`` replaced (as it was at `b413e01`);
* `numpy_cast_circles`: the lidar's and the camera's rays against people and pets (circles), every ray against every
  circle at once, which `atemr.io.sim.raycast.cast_circles`'s compiled loop replaced (as it was at `989bbad`);
* `numpy_sectorise`: the hex pattern's sectors of a scan (nearest, count and mean range of each), which
  `atemr.skills.hexpattern.sectorise`'s compiled loop replaced (as it was at `fb3fde7`);
* `NumpyFinishDepthCamera`: the simulated depth camera finishing its image (depth, noise, range, dropouts) with
  numpy passes and ``Generator``'s array draws, which `atemr.io.sim.depth`'s ``_finish`` replaced (as it was at
  `0fa2758`);
* `numpy_ramped_rollout` and `NumpyLocalPlanner`: the local planner's rollouts and its check of which are safe, in
  (targets × steps) arrays, which `atemr.skills.nav.local_planner`'s ``_rollout_poses`` and ``_rollouts_valid``
  replaced (as they were at `8afc15c`).

Kept as they were at `096bdec` unless said otherwise (renamed, with the helpers of their own) for two uses: the
benchmarks measure the compiled loops against them, and the tests check that the two answer with the same bits,
which is what keeps every seeded run the same as before (the one exception is `atemr.io.sim.raycast`'s face at an
exact grid corner).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.io.sim.depth import F32, DepthCamera
from atemr.io.sim.depth import _inverse as inverse_directions
from atemr.io.sim.raycast import FloatArray, GridHits, IntArray
from atemr.msgs import DepthImage, LaserScan, Pose2D, Twist
from atemr.skills.hexpattern import DEFAULT_RADIUS_M, HEX90, SECTORS, BasePoints, HexLayout, HexSectors, _layout_tables
from atemr.skills.localization.likelihood_field import DENSE_LOOKUPS, LikelihoodField
from atemr.skills.nav.costmap import MAX_NON_OBSTACLE, Costmap
from atemr.skills.nav.global_planner import _BLOCKED, _MOVES, PlannerParams
from atemr.skills.nav.local_planner import LocalPlanner, stop_cone_clearance
from atemr.skills.nav.voxel_layer import VoxelLayer

#: Crossings processed per chunk (per axis), after each jump over empty space.
CHUNK = 16
#: Most distance-transform jumps before each walk.
SKIPS = 4


class NumpyGridCaster:
    """The grid traversal before issue 22's compiled walk, vectorised in numpy over all rays at once.

    Besides the padded grid it keeps a distance transform (distance from every cell to the nearest blocked
    cell), used to jump each ray over empty space before walking cells exactly ("sphere tracing"): from a
    point whose cell is ``e`` cells from any blocked cell, the ray can advance ``e - 1.5`` cells without
    entering a blocked one (1.5 > the two half-diagonals between a point, its cell centre and a blocked
    cell's centre). Open rooms then cost one or two chunks per ray instead of one per 24 cells.
    """

    def __init__(self, blocked: NDArray[np.bool_], resolution_m: float) -> None:
        self.shape = blocked.shape
        self.resolution_m = float(resolution_m)
        height, width = blocked.shape
        padded = np.zeros((height + 2, width + 2), dtype=bool)
        padded[1:-1, 1:-1] = blocked
        self._blocked = blocked
        self._flat = padded.ravel()
        self._stride = width + 2
        # Outside the grid nothing blocks, but a ray may come back in: no skipping there (0).
        edt = np.zeros((height + 2, width + 2))
        edt[1:-1, 1:-1] = ndimage.distance_transform_edt(~blocked) if blocked.any() else np.inf
        self._edt = edt.ravel()

    def cast(self, origin_xy: tuple[float, float], angles_rad: FloatArray,  # noqa: PLR0915  the simulator's hot ray walk: its per-ray arrays stay in one frame
             max_range_m: float | FloatArray) -> GridHits:
        """One ray per angle from ``origin_xy`` (grid frame, metres from the lower-left corner), up to
        ``max_range_m`` (one range, or one per ray: the camera stops its furniture rays at the wall, so they
        end as soon as nothing in front of it can be left); cells outside the grid are empty."""
        res = self.resolution_m
        angles = np.asarray(angles_rad, dtype=np.float64)
        n = angles.shape[0]
        height, width = self.shape
        stride = self._stride
        flat_grid = self._flat
        gx0 = origin_xy[0] / res
        gy0 = origin_xy[1] / res
        t_max = np.asarray(max_range_m, dtype=np.float64) / res

        dist = np.full(n, np.inf)
        hit_row = np.full(n, -1, dtype=np.intp)
        hit_col = np.full(n, -1, dtype=np.intp)
        side = np.full(n, -1, dtype=np.int8)
        r0, c0 = math.floor(gy0), math.floor(gx0)
        if 0 <= r0 < height and 0 <= c0 < width and self._blocked[r0, c0]:
            return GridHits(np.zeros(n), np.full(n, r0, dtype=np.intp), np.full(n, c0, dtype=np.intp),
                            np.full(n, 2, dtype=np.int8))

        dx = np.cos(angles)
        dy = np.sin(angles)
        # Axis-parallel rays never cross lines of that axis: a tiny component pushes those crossings past range.
        dx = np.where(np.abs(dx) < 1e-12, np.copysign(1e-12, dx), dx)
        dy = np.where(np.abs(dy) < 1e-12, np.copysign(1e-12, dy), dy)
        inv_dx = np.abs(1.0 / dx)
        inv_dy = np.abs(1.0 / dy)
        pos_x = dx > 0
        pos_y = dy > 0
        x_step = np.where(pos_x, 1.0, -1.0)
        y_step = np.where(pos_y, 1.0, -1.0)
        # From a line index to the padded index of the cell entered through it: the line itself going
        # up/right, the one before it going down/left (+1 for the padding border).
        x_off = pos_x.astype(np.intp)
        y_off = pos_y.astype(np.intp)
        # Where a crossing lands exactly on a grid corner, the cell entered is the one the ray is heading into.
        nudge_x = np.copysign(1e-9, dx)
        nudge_y = np.copysign(1e-9, dy)

        # Where each ray leaves the grid (when it starts inside it): nothing beyond can stop it.
        t_lim = np.broadcast_to(t_max, (n,)).copy()
        inside = 0.0 <= gx0 <= width and 0.0 <= gy0 <= height
        if inside:
            tx_exit = np.abs(np.where(pos_x, float(width), 0.0) - gx0) * inv_dx
            ty_exit = np.abs(np.where(pos_y, float(height), 0.0) - gy0) * inv_dy
            t_lim = np.minimum(t_lim, np.minimum(tx_exit, ty_exit))

        # Both families of crossings at once: axis 0 walks vertical lines (x-faces), axis 1 horizontal ones.
        g0 = np.array([gx0, gy0])
        g_other = np.array([gy0, gx0])[None, :, None]
        d = np.stack([dx, dy], axis=1)  # (n, 2)
        d_other = np.stack([dy, dx], axis=1)[:, :, None]
        inv = np.stack([inv_dx, inv_dy], axis=1)[:, :, None]
        pos = np.stack([pos_x, pos_y], axis=1).astype(np.float64)
        step = np.stack([x_step, y_step], axis=1)[:, :, None]
        off = np.stack([x_off, y_off], axis=1)[:, :, None]
        nudge = np.stack([nudge_y, nudge_x], axis=1)[:, :, None]
        # Padded flat index = line cell * m_line + other cell * m_other (columns count 1, rows count stride).
        m_line = np.array([1, stride], dtype=np.intp)[None, :, None]
        m_other = np.array([stride, 1], dtype=np.intp)[None, :, None]
        hi_line = np.array([width + 1, height + 1])[None, :, None]
        hi_other = np.array([height + 1, width + 1])[None, :, None]
        k = np.arange(CHUNK, dtype=np.float64)[None, None, :]
        per_ray = np.concatenate([pos[:, :, None], step, inv, off.astype(np.float64), d_other, nudge], axis=2)

        cand_t = np.full(n, np.inf)
        cand_flat = np.zeros(n, dtype=np.intp)
        t_cur = np.zeros(n)
        alive = np.arange(n)
        while alive.size:
            a = alive
            ar = np.arange(a.size)
            lim = t_lim[a]
            da = d[a]
            # Jump over the empty space around the current point, again and again while the jumps are long
            # (cheap: one value per ray), so the exact walk below starts close to what the ray will meet.
            t0 = t_cur[a]
            for _ in range(SKIPS):
                p = g0 + t0[:, None] * da
                cell = np.floor(p).astype(np.intp) + 1
                if not inside:
                    cell = np.clip(cell, 0, [width + 1, height + 1])
                skip = np.maximum(self._edt.take(cell[:, 1] * stride + cell[:, 0], mode="clip") - 1.5, 0.0)
                t0 = np.minimum(t0 + skip, lim)
                if not (skip > 2.0).any():
                    break
            p = g0 + t0[:, None] * da
            # The next CHUNK lines of each family from there on, where they are crossed and the cell entered.
            ray = per_ray if a.size == n else per_ray[a]  # (a, 2, 6): one gather for all per-ray constants
            line = (np.floor(p) + ray[:, :, 0])[:, :, None] + ray[:, :, 1:2] * k  # (a, 2, CHUNK)
            t = np.abs(line - g0[None, :, None]) * ray[:, :, 2:3]
            cell_line = (line + ray[:, :, 3:4]).astype(np.intp)
            cell_other = np.floor(g_other + t * ray[:, :, 4:5] + ray[:, :, 5:6]).astype(np.intp) + 1
            if not inside:
                cell_line = np.clip(cell_line, 0, hi_line)
                cell_other = np.clip(cell_other, 0, hi_other)
            # From inside the grid every crossing within range is a cell of the padded grid; the others
            # (beyond the range, masked out) only need a valid index, which mode="clip" gives.
            flat = (cell_line * m_line + cell_other * m_other).reshape(a.size, 2 * CHUNK)
            t = t.reshape(a.size, 2 * CHUNK)
            t_hit = np.where(flat_grid.take(flat, mode="clip") & (t <= lim[:, None]), t, np.inf)
            j = t_hit.argmin(axis=1)
            best_t = t_hit[ar, j]
            # The nearest hit of this chunk is a candidate: the two families of one chunk cover different
            # distances, so a hit is final only once both have been examined up to it.
            better = best_t < cand_t[a]
            sel = a[better]
            cand_t[sel] = best_t[better]
            cand_flat[sel] = flat[ar, j][better]
            side[sel] = (j[better] >= CHUNK).astype(np.int8)
            covered = np.minimum(t[:, CHUNK - 1], t[:, 2 * CHUNK - 1])
            t_cur[a] = covered
            done = (cand_t[a] <= covered) | (covered >= lim)
            alive = a[~done]
        got = np.nonzero(np.isfinite(cand_t))[0]
        dist[got] = cand_t[got] * res
        hit_row[got] = cand_flat[got] // stride - 1
        hit_col[got] = cand_flat[got] % stride - 1
        return GridHits(dist, hit_row, hit_col, side)


class NumpyLikelihoodField(LikelihoodField):
    """`LikelihoodField` with its ``crossings`` and ``_indices`` as numpy computed them before the compiled loops."""

    def _indices(self, poses: FloatArray, points: FloatArray) -> NDArray[np.intp]:
        """Cell index of every point under every pose: ``(N, M)``.

        The ``N × M`` arithmetic runs in float32 (twice as fast; a tenth of a millimetre at 1 km from the
        origin, far below a cell), the pose transforms in float64."""
        with np.errstate(invalid="ignore", over="ignore"):
            g = self._to_grid_frame(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
            c = np.cos(g[:, 2]).astype(np.float32)[:, None]
            s = np.sin(g[:, 2]).astype(np.float32)[:, None]
            gx0 = g[:, 0:1].astype(np.float32)
            gy0 = g[:, 1:2].astype(np.float32)
            px = points[:, 0].astype(np.float32)[None, :]
            py = points[:, 1].astype(np.float32)[None, :]
        with np.errstate(invalid="ignore", over="ignore"):  # absurd poses land off the map, never warn
            gx = c * px
            gx -= s * py
            gx += gx0
            gy = s * px
            gy += c * py
            gy += gy0
        return self._flat_index(gx, gy)

    def crossings(self, poses: FloatArray, start_xy: tuple[float, float], points: FloatArray,
                  stop_short_m: float) -> NDArray[np.bool_]:
        """Whether the segment from ``start_xy`` to each base-frame point, ending ``stop_short_m`` before the
        point, enters an occupied cell, under every pose: ``(N, M)``.

        Few segments are sampled every half cell (the samples are the same base-frame points under every
        pose: one look-up); many are walked by sphere tracing (`_crossings_traced`), which costs a few
        steps per segment in open space instead of one per half cell.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        n = np.asarray(poses).reshape(-1, 3).shape[0]
        if pts.shape[0] == 0 or n == 0:
            return np.zeros((n, pts.shape[0]), dtype=bool)
        start = np.asarray(start_xy, dtype=np.float64).reshape(1, 2)
        ray = pts - start
        length = np.hypot(ray[:, 0], ray[:, 1])
        reach = np.maximum(length - stop_short_m, 0.0)
        samples = max(2, math.ceil(float(reach.max()) / (0.5 * self.map.resolution_m)) + 1)
        if n * pts.shape[0] * samples > DENSE_LOOKUPS:
            return self._crossings_traced(poses, start[0], ray, length, reach)
        scale = np.divide(reach, length, out=np.zeros_like(length), where=length > 0)
        frac = np.linspace(0.0, 1.0, samples)[None, :, None]
        along = start[:, None, :] + (scale[:, None, None] * frac) * ray[:, None, :]
        inside = self.distances(poses, along.reshape(-1, 2)).reshape(n, pts.shape[0], samples) <= 0.0
        return np.asarray(inside.any(axis=2), dtype=bool)

    def _crossings_traced(self, poses: FloatArray, start: FloatArray, ray: FloatArray, length: FloatArray,
                          reach: FloatArray) -> NDArray[np.bool_]:
        """`crossings` by sphere tracing: from a point whose cell is ``d`` from the nearest occupied cell centre,
        nothing occupied lies within ``d − res·√2``, so every segment jumps that far (at least half a cell)."""
        g = self._to_grid_frame(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
        n, m = g.shape[0], ray.shape[0]
        c, s = np.cos(g[:, 2])[:, None], np.sin(g[:, 2])[:, None]
        x0 = ((g[:, 0:1] + c * start[0] - s * start[1]) + np.zeros((1, m))).ravel()
        y0 = ((g[:, 1:2] + s * start[0] + c * start[1]) + np.zeros((1, m))).ravel()
        unit = np.divide(ray, length[:, None], out=np.zeros_like(ray), where=length[:, None] > 0)
        ux, uy = (c * unit[:, 0] - s * unit[:, 1]).ravel(), (s * unit[:, 0] + c * unit[:, 1]).ravel()
        end = np.broadcast_to(reach, (n, m)).ravel()
        res = self.map.resolution_m
        margin, least = res * math.sqrt(2.0), 0.5 * res
        crossed = np.zeros(n * m, dtype=bool)
        t = np.zeros(n * m)
        live = np.arange(n * m)
        while live.size:
            tl = t[live]
            d = self._dist_flat[self._flat_index(x0[live] + ux[live] * tl, y0[live] + uy[live] * tl)]
            inside = d <= 0.0
            crossed[live[inside]] = True
            t[live] = np.minimum(tl + np.maximum(d - margin, least), end[live])
            live = live[~inside & (tl < end[live])]  # one last look exactly at the end, then stop
        return crossed.reshape(n, m)


class NumpyMarkLayer(VoxelLayer):
    """`VoxelLayer` with its ``_mark`` as numpy computed it before the compiled loop."""

    def _mark(self, image: DepthImage, frame: tuple[float, float, float, float], scan: LaserScan | None
              ) -> NDArray[np.int32]:
        """Set the voxels that hold at least ``min_points`` of the frame's points within ``mark_range_m``, away from
        the map's and the lidar's obstacles; returns their flat indices."""
        p = self.params
        pts = self._projector.points(image)
        origin = self._projector.origin
        plan_sq = (pts[:, 0] - origin[0]) ** 2 + (pts[:, 1] - origin[1]) ** 2
        near = plan_sq <= np.float32(p.mark_range_m ** 2)
        flat, inside = self._flat(pts[near], frame)
        flat = flat[inside]
        match = np.maximum(np.float32(self._min_match), np.float32(p.wall_match_m) + np.float32(p.wall_match_per_m)
                           * np.sqrt(plan_sq[near][inside]))
        flat = flat[self._static_flat[flat // p.layers] > match]
        if scan is not None and len(flat):
            flat = flat[~self._lidar_sees(flat // p.layers, scan, frame)]
        if len(flat) and p.min_points > 1:
            voxels, counts = np.unique(flat, return_counts=True)
            flat = voxels[counts >= p.min_points]
        self._voxels_flat[flat] = True
        return flat


class NumpyShapesDepthCamera(DepthCamera):
    """`DepthCamera` with its furniture and people hit by numpy slab and cylinder tests over pixel slices."""

    def _hit_shapes(self, t_hit: F32, shapes: list[tuple[tuple[int, int], str, tuple[float, ...], tuple[float, float]]],
                    origin: tuple[float, float, float], turn: tuple[float, float]) -> None:
        """Lower ``t_hit`` (sorted pixels) to each shape's hits: (pixel span, "box" or "circle", its plan
        outline, (bottom, top) heights). The rays are turned to the world and inverted only over the pixels
        the shapes span, once for all of them."""
        lo, hi = min(a for (a, _), *_ in shapes), max(b for (_, b), *_ in shapes)
        c, s = np.float32(turn[0]), np.float32(turn[1])
        d = self._dir[lo:hi]
        dx = c * d[:, 0] - s * d[:, 1]
        dy = s * d[:, 0] + c * d[:, 1]
        dz = self._dz_safe[lo:hi]
        inv: tuple[F32, F32, F32] | None = None
        for (a, b), shape, outline, (bottom, top) in shapes:
            i, j = a - lo, b - lo
            if shape == "box":
                if inv is None:  # inverse directions once per frame for every box's slab test
                    inv = (inverse_directions(dx), inverse_directions(dy), self._inv_dz[lo:hi])
                x0, y0, x1, y1 = outline
                hit = numpy_box_hits(origin, (inv[0][i:j], inv[1][i:j], inv[2][i:j]), (x0, y0, bottom), (x1, y1, top))
            else:
                hit = numpy_cylinder_hits(origin, (dx[i:j], dy[i:j], dz[i:j]), outline, (bottom, top))
            np.minimum(t_hit[a:b], hit, out=t_hit[a:b])


class NumpyFinishDepthCamera(DepthCamera):
    """`DepthCamera` finishing its image with numpy and ``Generator``'s array draws (as it was at `0fa2758`)."""

    def _image(self, t_hit: F32) -> F32:
        p = self.params
        sorted_depth = np.minimum(t_hit, np.float32(1e3))  # nothing hit: far beyond range
        sorted_depth *= self._depth_per_t
        depth = sorted_depth.take(self._unsort)
        if p.subpixel_px:
            depth += p.noise_std_m(depth) * self.rng.standard_normal(depth.shape, dtype=np.float32)
        out_of_range = ~((depth >= p.range_min_m) & (depth <= p.range_max_m))
        if p.dropout_prob:
            out_of_range |= self.rng.random(depth.shape, dtype=np.float32) < p.dropout_prob
        depth[out_of_range] = 0.0
        return depth


def numpy_box_hits(origin: tuple[float, float, float], inv: tuple[F32, F32, F32], lo: tuple[float, float, float],
              hi: tuple[float, float, float]) -> F32:
    """Distance along each ray (given by its inverse direction, no component 0) to an axis-aligned box (slab
    test); inf where it misses or lies behind."""
    t_enter: F32 | None = None
    t_exit: F32 | None = None
    for o, inv_d, a, b in zip(origin, inv, lo, hi, strict=True):
        t1 = np.float32(a - o) * inv_d
        t2 = np.float32(b - o) * inv_d
        near, far = np.minimum(t1, t2), np.maximum(t1, t2)
        t_enter = near if t_enter is None else np.maximum(t_enter, near, out=t_enter)
        t_exit = far if t_exit is None else np.minimum(t_exit, far, out=t_exit)
    assert t_enter is not None and t_exit is not None
    out: F32 = np.where((t_exit >= t_enter) & (t_enter > 0), t_enter, np.float32(np.inf))
    return out


def numpy_cylinder_hits(origin: tuple[float, float, float], rays: tuple[F32, F32, F32], circle: tuple[float, ...],
                   heights: tuple[float, float]) -> F32:
    """Distance along each ray to a vertical cylinder spanning ``heights`` (bottom, top), its side or its caps."""
    ox, oy, oz = origin
    dx, dy, dz = rays
    bottom_m, top_m = heights
    cx, cy, r = circle
    fx, fy = np.float32(ox - cx), np.float32(oy - cy)
    a = dx * dx + dy * dy
    b = fx * dx + fy * dy
    c = np.float32(fx * fx + fy * fy - r * r)
    disc = b * b - a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        t_side = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        z = oz + t_side * dz
        side = np.where((disc >= 0) & (t_side >= 0) & (z >= bottom_m) & (z <= top_m), t_side, np.inf)
        # the caps: the top seen from above, the bottom from below
        cap_z = np.where(dz < 0, np.float32(top_m), np.float32(bottom_m))
        t_cap = (cap_z - np.float32(oz)) / dz
        hx, hy = fx + t_cap * dx, fy + t_cap * dy
        cap = np.where((t_cap >= 0) & (hx * hx + hy * hy <= r * r) & (dz != 0), t_cap, np.inf)
    out: F32 = np.minimum(side, cap).astype(np.float32)
    return out


def numpy_cast_circles(
    origin_xy: tuple[float, float],
    angles_rad: FloatArray,
    centres_xy: FloatArray,
    radii_m: FloatArray,
    max_range_m: float = math.inf,
) -> tuple[FloatArray, IntArray]:
    """Distance along each ray to the nearest circle, and that circle's index (-1: none within range): every ray
    against every circle as (rays, circles) arrays, as `atemr.io.sim.raycast.cast_circles` did at `989bbad`.

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


def numpy_sectorise(points: BasePoints, layout: HexLayout = HEX90, radius_m: float = DEFAULT_RADIUS_M) -> HexSectors:
    """Base-frame points reduced to the six sectors of ``layout`` with numpy: a searchsorted, ``np.minimum.at`` and
    two ``np.bincount``."""
    first, edges, to_canonical = _layout_tables(layout)
    rel = np.mod(points.bearing_rad - first, 2.0 * math.pi)
    in_layout = np.searchsorted(edges, rel, side="right") - 1
    idx = to_canonical[np.clip(in_layout, 0, len(SECTORS) - 1)]
    n = len(SECTORS)
    nearest = np.full(n, np.inf)
    np.minimum.at(nearest, idx, points.range_m)
    near = points.range_m <= radius_m
    count = np.bincount(idx[near], minlength=n)
    total = np.bincount(idx[near], weights=points.range_m[near], minlength=n)
    mean = np.where(count > 0, total / np.maximum(count, 1), radius_m)
    return HexSectors(layout, float(radius_m), mean, nearest, count.astype(np.int64))


def _shifted(padded: NDArray[Any], dr: int, dc: int) -> NDArray[Any]:
    """The view of a one-cell-padded grid seen from each cell's neighbour at (dr, dc)."""
    rows, cols = padded.shape[0] - 2, padded.shape[1] - 2
    return padded[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]


#: Cells whose weights are built at once, in a band of whole rows: their eight planes (8 x 32,768 floats) stay in the
#: processor's cache until they are interleaved into the CSR layout, instead of a whole grid's going out and back.
_CELLS_AT_ONCE = 32_768


def numpy_edge_weights(cost: NDArray[np.uint8], passable: NDArray[np.bool_], resolution_m: float,
                 params: PlannerParams, potential: FloatArray | None = None) -> NDArray[np.float64]:
    """(N, 8) weight of every neighbour slot: the cost-aware length of the step into that neighbour.

    With ``potential`` (A*'s heuristic per cell), the reduced weight ``w − h(u) + h(v)`` instead, clamped at a
    tiny positive value. Each direction is computed in place on a contiguous plane from shifted views of
    padded grids (no gathers), a band of rows at a time, and the band's planes are interleaved into the CSR
    row layout in one copy: a 400x400 grid takes a few milliseconds.
    """
    rows, cols = cost.shape
    per_m = params.neutral_cost + params.cost_factor * np.minimum(cost, MAX_NON_OBSTACLE) / MAX_NON_OBSTACLE
    per_m_pad = np.pad(per_m, 1)
    ok_pad = np.pad(passable, 1, constant_values=False)
    h_pad = np.pad(potential, 1) if potential is not None else None
    out = np.empty((rows, cols, 8), dtype=np.float64)
    band_rows = min(max(_CELLS_AT_ONCE // cols, 1), rows)
    band = np.empty((8, band_rows, cols), dtype=np.float64)
    for r0 in range(0, rows, band_rows):
        r1 = min(rows, r0 + band_rows)
        planes = band[:, :r1 - r0]
        for k, (dr, dc) in enumerate(_MOVES):
            ok = _shifted(ok_pad, dr, dc)[r0:r1]
            if dr and dc:  # no corner cutting: both orthogonal cells passed between must be passable
                ok = ok & _shifted(ok_pad, dr, 0)[r0:r1] & _shifted(ok_pad, 0, dc)[r0:r1]
            w = planes[k]
            np.multiply(_shifted(per_m_pad, dr, dc)[r0:r1], math.hypot(dr, dc) * resolution_m, out=w)
            if h_pad is not None and potential is not None:
                w += _shifted(h_pad, dr, dc)[r0:r1]
                w -= potential[r0:r1]
                np.maximum(w, 1e-12, out=w)
            np.copyto(w, _BLOCKED, where=~ok)
        out[r0:r1] = planes.transpose(1, 2, 0)
    return out.reshape(rows * cols, 8)


class NumpyClearingCostmap(Costmap):
    """`Costmap` with its clearing as numpy computed it before the compiled loop: every beam's samples at once."""

    def _clear(self, sensor: tuple[float, float], beams: tuple[FloatArray, FloatArray, FloatArray]) -> None:
        sx, sy = sensor
        ux, uy, reach = beams
        step = self.resolution_m / 2
        n = int(max(reach.max(), 0.0) / step) + 1
        t = np.arange(n, dtype=np.float64) * step
        along = t[None, :] <= reach[:, None]
        cx = (sx + ux[:, None] * t[None, :])[along]
        cy = (sy + uy[:, None] * t[None, :])[along]
        row, col, inside = self.cells(cx, cy)
        self.obstacles[row[inside], col[inside]] = False


def numpy_ramped_rollout(pose: Pose2D, velocity: Twist, v_target: FloatArray, w_target: FloatArray, *, step_s: float,
                         steps: int, linear_accel: float, angular_accel: float
                         ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """`atemr.skills.nav.local_planner.ramped_rollout` as numpy computed it: all targets at once."""
    t_mid = (np.arange(steps, dtype=np.float64) + 0.5) * step_s
    dv = np.clip(v_target[:, None] - velocity.linear_mps, -linear_accel * t_mid, linear_accel * t_mid)
    dw = np.clip(w_target[:, None] - velocity.angular_radps, -angular_accel * t_mid, angular_accel * t_mid)
    v = velocity.linear_mps + dv
    w = velocity.angular_radps + dw
    yaw = pose.yaw_rad + np.cumsum(w * step_s, axis=1)
    yaw_mid = yaw - w * (step_s / 2)
    x = pose.x_m + np.cumsum(v * np.cos(yaw_mid) * step_s, axis=1)
    y = pose.y_m + np.cumsum(v * np.sin(yaw_mid) * step_s, axis=1)
    return x, y, yaw


class NumpyLocalPlanner(LocalPlanner):
    """`LocalPlanner` rolling out and checking its rollouts with numpy arrays."""

    def _rollout(self, pose: Pose2D, velocity: Twist, vs: FloatArray, ws: FloatArray, horizon_s: float
                 ) -> tuple[FloatArray, FloatArray, FloatArray]:
        p = self.params
        steps = max(round(horizon_s / p.sim_step_s), 1)
        return numpy_ramped_rollout(pose, velocity, vs, ws, step_s=p.sim_step_s, steps=steps,
                                    linear_accel=p.linear_accel_mps2, angular_accel=p.angular_accel_radps2)

    def _valid(self, pose: Pose2D, xs: FloatArray, ys: FloatArray, th: FloatArray, *, vs: FloatArray,
               clearance_here: float) -> NDArray[np.bool_]:
        p, cm = self.params, self.costmap
        r_in = cm.params.inscribed_radius_m
        clear = cm.distance_at(xs, ys)
        floor = min(r_in, clearance_here)
        first_cell = np.hypot(xs - pose.x_m, ys - pose.y_m) < cm.resolution_m
        valid = np.where(first_cell, clear >= floor - cm.resolution_m, clear >= floor).all(axis=1)
        if clearance_here < r_in:
            valid &= clear[:, -1] > clearance_here
            hard_here = float(cm.static_distance_at(pose.x_m, pose.y_m))
            hard = cm.static_distance_at(xs, ys)
            floor = min(r_in + 0.05, hard_here)
            valid &= (hard.min(axis=1) >= floor) & (hard[:, -1] >= floor)
        direction = np.sign(vs)[:, None] * np.ones_like(xs)
        cone = stop_cone_clearance(cm, xs, ys, th, direction=direction, radius_m=p.stop_cone_m).min(axis=1)
        cone_here = float(stop_cone_clearance(cm, np.array([pose.x_m]), np.array([pose.y_m]),
                                              np.array([pose.yaw_rad]), direction=np.array([1.0]),
                                              radius_m=p.stop_cone_m)[0])
        valid &= cone >= min(1.0, cone_here)
        return valid
