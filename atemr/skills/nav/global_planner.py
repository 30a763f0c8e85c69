"""Global planner: A* and Dijkstra on the costmap (8-connected, cost-aware), then path smoothing.

Why it is fast without a Python loop per node: the grid is a fixed sparse graph (every cell has eight
neighbour slots, a CSR matrix whose structure depends only on the grid's shape and is built once), and
the search runs in scipy's compiled Dijkstra (`scipy.sparse.csgraph.dijkstra`).

A* is Dijkstra on *reduced costs* (Johnson's potential): with a consistent heuristic ``h`` (octile
distance to the goal times the cheapest cost per metre), the weight ``w'(u, v) = w(u, v) − h(u) + h(v)``
is never negative, and a shortest path under ``w'`` is a shortest path under ``w`` whose length is
``d'(s, g) + h(s) − h(g)``. Dijkstra's ``limit`` on reduced distance is a bound on A*'s ``f = g + h``, so a
search limited to ``L`` expands exactly the nodes A* would expand with ``f ≤ h(s) + L``. The planner starts
with a bound and doubles it until the goal is reached (or the reachable set stops growing:
no path), so it expands about what A* expands, at compiled speed.

Edge cost (ROS global_planner's): ``length_m · (neutral_cost + cost_factor · cell_cost / 252)`` of the
cell entered; cells at or above ``INSCRIBED`` cannot be entered (unknown ones only with
``allow_unknown``), and a diagonal step may not cut the corner of a blocked cell.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from atemr.errors import NavigationError
from atemr.skills.nav.costmap import INSCRIBED, MAX_NON_OBSTACLE, NO_INFORMATION, Costmap

FloatArray = NDArray[np.float64]
Algorithm = Literal["astar", "dijkstra"]

#: Weight of an edge into a blocked cell: present in the fixed CSR structure, never on a real path.
_BLOCKED = 1e12
#: Cells per side of the blocks of the coarse grid whose plan sets A*'s first bound (`coarse_cost`).
COARSE_BLOCK = 4
#: (d_row, d_col) of the eight neighbours, in increasing order of flat offset (sorted CSR columns).
_MOVES = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


@dataclass(frozen=True)
class PlannerParams:
    """Search settings; ``cost_factor`` trades path length against distance from obstacles."""

    algorithm: Algorithm = "astar"
    neutral_cost: float = 1.0
    cost_factor: float = 3.0
    allow_unknown: bool = False
    #: Around a start that lies in the inscribed zone (robot pushed against a wall), inscribed cells within
    #: this radius may be crossed, so the robot can plan its way out instead of reporting "no path".
    escape_radius_m: float = 0.35
    smooth: bool = True

    def __post_init__(self) -> None:
        if self.algorithm not in ("astar", "dijkstra"):
            raise NavigationError(f"planner: algorithm must be 'astar' or 'dijkstra', got {self.algorithm!r}")
        if not (math.isfinite(self.neutral_cost) and self.neutral_cost > 0):
            raise NavigationError(f"planner: neutral_cost must be > 0, got {self.neutral_cost!r}")
        if not (math.isfinite(self.cost_factor) and self.cost_factor >= 0):
            raise NavigationError(f"planner: cost_factor must be >= 0, got {self.cost_factor!r}")


@dataclass(frozen=True)
class GlobalPath:
    """A plan: world points (N, 2) from start to goal, its length and cost, and the raw grid cells."""

    points: FloatArray
    cells: NDArray[np.intp]
    length_m: float
    cost: float
    expanded: int

    @property
    def raw_length_m(self) -> float:
        return self.length_m


@functools.lru_cache(maxsize=8)
def _structure(rows: int, cols: int) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
    """CSR indptr and column indices of the 8-neighbour grid graph (a slot off the grid points at the node
    itself and always gets the blocked weight)."""
    n = rows * cols
    r, c = np.divmod(np.arange(n, dtype=np.int64), cols)
    nbr = np.empty((n, 8), dtype=np.int32)
    for k, (dr, dc) in enumerate(_MOVES):
        rr, cc = r + dr, c + dc
        inside = (rr >= 0) & (rr < rows) & (cc >= 0) & (cc < cols)
        nbr[:, k] = np.where(inside, rr * cols + cc, np.arange(n))
    indptr = np.arange(0, 8 * n + 1, 8, dtype=np.int32)
    indices = nbr.reshape(-1)
    indptr.setflags(write=False)
    indices.setflags(write=False)
    return indptr, indices


def edge_weights(cost: NDArray[np.uint8], passable: NDArray[np.bool_], resolution_m: float,
                 params: PlannerParams, potential: FloatArray | None = None) -> NDArray[np.float64]:
    """(N, 8) weight of every neighbour slot: the cost-aware length of the step into that neighbour.

    With ``potential`` (A*'s heuristic per cell), the reduced weight ``w − h(u) + h(v)`` instead, clamped at a
    tiny positive value. A compiled loop over the cells (`_weights_into`): the numpy version it replaced, kept in
    ``benchmarks/numpy_baselines.py``, made a dozen passes over the grid per direction, and a new goal on a large
    map pays for every cell's weights.
    """
    rows, cols = cost.shape
    per_m = params.neutral_cost + params.cost_factor * np.minimum(cost, MAX_NON_OBSTACLE) / MAX_NON_OBSTACLE
    steps = np.array([math.hypot(dr, dc) * resolution_m for dr, dc in _MOVES])
    h = np.zeros((0, 0)) if potential is None else np.ascontiguousarray(potential, dtype=np.float64)
    out = np.empty((rows * cols, 8), dtype=np.float64)
    _weights_into(per_m, np.ascontiguousarray(passable), steps, h, out)
    return out


@njit(cache=True, nogil=True)
def _weights_into(per_m: FloatArray, passable: NDArray[np.bool_], steps: FloatArray, potential: FloatArray,
                  out: FloatArray) -> None:  # pragma: no cover  compiled by numba
    """Each cell's eight weights in `_MOVES` order: the step's length times the entered cell's cost per metre, plus
    h(v) − h(u) and at least 1e-12 when ``potential`` is given (not empty); `_BLOCKED` into a cell that cannot be
    entered, off the grid or across a corner (a diagonal step needs both cells it passes between)."""
    rows, cols = per_m.shape
    reduced = potential.shape[0] > 0
    for r in range(rows):
        for c in range(cols):
            u = r * cols + c
            for k in range(8):
                dr, dc = _MOVES[k]
                rr, cc = r + dr, c + dc
                ok = 0 <= rr < rows and 0 <= cc < cols and passable[rr, cc]
                if ok and dr != 0 and dc != 0:
                    ok = passable[rr, c] and passable[r, cc]
                if not ok:
                    out[u, k] = _BLOCKED
                    continue
                w = per_m[rr, cc] * steps[k]
                if reduced:
                    w = max(w + potential[rr, cc] - potential[r, c], 1e-12)
                out[u, k] = w


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) `_weights_into` when the first planner is
    built, not at the robot's first plan: the call has the argument types of `edge_weights`' (a test checks that
    a running robot has one compiled version of each loop)."""
    _weights_into(np.ones((1, 1)), np.ones((1, 1), dtype=np.bool_), np.ones(8), np.zeros((0, 0)), np.empty((1, 8)))


def octile_m(rows: NDArray[np.intp], cols: NDArray[np.intp], goal: tuple[int, int], resolution_m: float
             ) -> FloatArray:
    """Octile distance (metres) from cells to ``goal``: the shortest 8-connected length on an empty grid."""
    dr = np.abs(rows - goal[0]).astype(np.float64)
    dc = np.abs(cols - goal[1]).astype(np.float64)
    return (np.maximum(dr, dc) + (math.sqrt(2) - 1) * np.minimum(dr, dc)) * resolution_m


class GlobalPlanner:
    """Plans on a `Costmap`; caches the edge weights for the costmap's current version."""

    def __init__(self, costmap: Costmap, params: PlannerParams | None = None) -> None:
        self.costmap = costmap
        self.params = params or PlannerParams()
        load_compiled()
        #: (goal the weights are reduced for, None: plain; the cost and passability they were built from; weights)
        self._cached: tuple[tuple[int, int] | None, NDArray[np.uint8], NDArray[np.bool_], NDArray[np.float64]] | None \
            = None
        #: The goal of the last plan, the (reduced) cost from each cell of its path to the goal, and the path.
        self._to_go: tuple[int, dict[int, float], NDArray[np.intp]] | None = None

    def _passable(self) -> NDArray[np.bool_]:
        return self.costmap.traversable(allow_unknown=self.params.allow_unknown)

    def _cell(self, x: float, y: float, what: str) -> tuple[int, int]:
        if not (math.isfinite(x) and math.isfinite(y)):
            raise NavigationError(f"planner: {what} must be finite, got ({x}, {y})")
        row, col, inside = self.costmap.cells(x, y)
        if not bool(inside):
            raise NavigationError(f"planner: {what} ({x:.2f}, {y:.2f}) is outside the map '{self.costmap.map.name}'")
        return int(row), int(col)

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float], *, tolerance_m: float = 0.0
             ) -> GlobalPath | None:
        """The cheapest path from ``start_xy`` to ``goal_xy`` (world metres), or None when there is none.

        ``tolerance_m``: when the goal cell itself cannot be entered (a chair was put there, a person stands
        next to it), plan to the enterable cell nearest the goal within this distance instead (global_planner's
        ``default_tolerance``); the path then ends at that cell.
        """
        cm = self.costmap
        p = self.params
        s = self._cell(*start_xy, what="start")
        g = self._cell(*goal_xy, what="goal")
        cols = cm.shape[1]
        if not self._enterable(g):
            near = self._nearest_enterable(g, tolerance_m)
            if near is None:
                return None
            g = near
            gx, gy = cm.map.cell_to_world(g[0], g[1])
            goal_xy = (float(gx), float(gy))
        s_flat, g_flat = s[0] * cols + s[1], g[0] * cols + g[1]
        if s_flat == g_flat:
            pts = np.array([start_xy, goal_xy], dtype=np.float64)
            return GlobalPath(pts, np.array([s_flat]), float(np.hypot(*(pts[1] - pts[0]))), 0.0, 1)
        h: FloatArray | None = None
        h_start = 0.0
        if p.algorithm == "astar":
            h = _potential(cm.shape, g, cm.resolution_m, p)
            h_start = float(h[s])
        cost_grid, passable = self._grids(s)
        graph = _graph(self._weights(cost_grid, passable, h, g), cm.shape)
        # The first bound, doubled until the goal is inside (the total work stays within a small factor of the
        # last search's). A replan along the last path knows its cost to go. Otherwise A* takes the cost a plan on
        # a coarse grid estimates, a quarter above it (`coarse_cost`); Dijkstra, or a replan whose known cost
        # no longer holds, a share of the straight line (`_share_of_straight`).
        known = self._known_cost_to_go(s_flat, g_flat)
        if p.algorithm == "astar" and known is None:
            estimate = coarse_cost(cost_grid, passable, s, g, resolution_m=cm.resolution_m, params=p)
            if estimate is None:  # no path on the coarse grid, so none on this one (`coarse_cost`)
                return None
            limit = 1.25 * max(estimate - h_start, 0.0) + 2 * COARSE_BLOCK * cm.resolution_m * p.neutral_cost
        else:
            straight = float(octile_m(np.array(s[0]), np.array(s[1]), g, cm.resolution_m)) * p.neutral_cost
            limit = _share_of_straight(straight, cm.resolution_m, p.algorithm)
        found = _bounded_search(graph, s_flat, g_flat, limit, known)
        if found is None:
            return None
        d_goal, pred, dist, expanded = found
        flat = _walk_back(pred, s_flat, g_flat)
        # The (reduced) cost to go from every cell of this path: a replan to the same goal from one of them (the
        # robot follows the path) searches with that bound, which a generous first bound would overshoot.
        self._to_go = (g_flat, dict(zip(flat.tolist(), (d_goal - dist[flat]).tolist(), strict=True)), flat)
        pr, pc = np.divmod(flat, cols)
        x, y = cm.map.cell_to_world(pr, pc)
        pts = np.column_stack([x, y]).astype(np.float64)
        pts[0] = start_xy
        pts[-1] = goal_xy
        total = d_goal + h_start  # reduced distance + h(s) − h(g), h(g) = 0
        if p.smooth:
            pts = smooth_path(pts, cm)
        seg = np.diff(pts, axis=0)
        length = float(np.hypot(seg[:, 0], seg[:, 1]).sum())
        return GlobalPath(pts, flat, length, total, expanded)

    def _known_cost_to_go(self, s_flat: int, g_flat: int) -> float | None:
        """The last plan's (reduced) cost from ``s_flat`` to the goal when it went to the same goal through that
        cell and no edge of it changed since (`_weights` forgets the path then): the bound the search needs. A
        hair above it, as the search adds the same weights in another order."""
        if self._to_go is None or self._to_go[0] != g_flat:
            return None
        known = self._to_go[1].get(s_flat)
        return None if known is None else known * (1 + 1e-9) + 1e-9

    def _weights(self, cost: NDArray[np.uint8], passable: NDArray[np.bool_], potential: FloatArray | None,
                 goal: tuple[int, int]) -> NDArray[np.float64]:
        """The (N, 8) edge weights, reduced by ``potential`` for A* (built in one pass for a new goal: a first
        plan pays for one sweep of the grid, not two). They are cached with the costmap they were built from
        and, when the costmap changed, patched only around the cells that changed (the obstacle layer moves a
        few cells per scan), so a replan on a big map does not rebuild millions of weights."""
        cm = self.costmap
        rows, cols = cost.shape
        key = goal if potential is not None else None
        if self._cached is None or self._cached[1].shape != cost.shape or self._cached[0] != key:
            weights = edge_weights(cost, passable, cm.resolution_m, self.params, potential)
            self._cached = (key, cost.copy(), passable.copy(), weights)
            return weights
        _, old_cost, old_ok, weights = self._cached
        changed = (cost != old_cost) | (passable != old_ok)
        if changed.any():
            rr = np.flatnonzero(changed.any(axis=1))
            cc = np.flatnonzero(changed.any(axis=0))
            # Edges of cells next to a change change too (entered cell, corner rule): patch the box grown by 1,
            # computed on the box grown by 2 so every patched cell sees its true neighbours (and potentials).
            t0, t1 = max(int(rr[0]) - 1, 0), min(int(rr[-1]) + 2, rows)
            u0, u1 = max(int(cc[0]) - 1, 0), min(int(cc[-1]) + 2, cols)
            s0, s1 = max(t0 - 1, 0), min(t1 + 1, rows)
            v0, v1 = max(u0 - 1, 0), min(u1 + 1, cols)
            sub = edge_weights(cost[s0:s1, v0:v1], passable[s0:s1, v0:v1], cm.resolution_m, self.params,
                               None if potential is None else potential[s0:s1, v0:v1])
            sub = sub.reshape(s1 - s0, v1 - v0, 8)[t0 - s0:t1 - s0, u0 - v0:u1 - v0]
            weights.reshape(rows, cols, 8)[t0:t1, u0:u1] = sub
            if self._to_go is not None:  # the last path's cost holds only if none of its edges changed
                pr, pc = np.divmod(self._to_go[2], cols)
                if np.any((pr >= t0) & (pr < t1) & (pc >= u0) & (pc < u1)):
                    self._to_go = None
            old_cost[t0:t1, u0:u1] = cost[t0:t1, u0:u1]
            old_ok[t0:t1, u0:u1] = passable[t0:t1, u0:u1]
        return weights

    def _enterable(self, cell: tuple[int, int]) -> bool:
        c = int(self.costmap.cost[cell])
        return c < INSCRIBED or (self.params.allow_unknown and c == NO_INFORMATION)

    def _nearest_enterable(self, cell: tuple[int, int], tolerance_m: float) -> tuple[int, int] | None:
        cm = self.costmap
        rad = int(tolerance_m / cm.resolution_m)
        if rad <= 0:
            return None
        r0, c0 = max(cell[0] - rad, 0), max(cell[1] - rad, 0)
        window = cm.cost[r0:cell[0] + rad + 1, c0:cell[1] + rad + 1]
        ok = window < INSCRIBED
        if self.params.allow_unknown:
            ok |= window == NO_INFORMATION
        rr, cc = np.nonzero(ok)
        if len(rr) == 0:
            return None
        d = np.hypot(rr + r0 - cell[0], cc + c0 - cell[1])
        best = int(np.argmin(d))
        if d[best] > rad:
            return None
        return int(rr[best] + r0), int(cc[best] + c0)

    def _grids(self, start: tuple[int, int]) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
        """Cost and passability for a search from ``start``: when the start lies in the inscribed zone (the
        robot pushed against a wall), inscribed (never lethal) cells near it become passable at the highest
        cost, so the robot can plan its way out instead of reporting "no path"."""
        cm = self.costmap
        cost = cm.cost
        passable = self._passable()
        if cost[start] < INSCRIBED:
            return cost, passable
        rows, cols = cm.shape
        rad = math.ceil(self.params.escape_radius_m / cm.resolution_m)
        r0, r1 = max(start[0] - rad, 0), min(start[0] + rad + 1, rows)
        c0, c1 = max(start[1] - rad, 0), min(start[1] + rad + 1, cols)
        cost = cost.copy()
        passable = passable.copy()
        window = cost[r0:r1, c0:c1]
        passable[r0:r1, c0:c1] |= window == INSCRIBED
        window[window == INSCRIBED] = MAX_NON_OBSTACLE
        return cost, passable


def coarse_cost(cost: NDArray[np.uint8], passable: NDArray[np.bool_], start: tuple[int, int], goal: tuple[int, int], *,
                resolution_m: float, params: PlannerParams) -> float | None:
    """The cost of the cheapest path from the cell ``start`` to ``goal`` on a grid `COARSE_BLOCK` times coarser, or
    None when that grid has none. A block is passable when any of its cells is, at the cost of the cheapest.

    None means the full grid has no path either: every step of a path on it is a step between the blocks of its two
    cells, or none, and a diagonal step's two corner cells lie in the two blocks the coarse step's corner rule asks
    for, so every path on the full grid is one on the coarse grid. A plan that has no path (a doorway closed) is
    known at a sixteenth of the cost of searching the full grid until it stops growing.

    An estimate of the full grid's path cost for a sixteenth of the work, which A* takes for its first bound. With
    a fixed share of the straight line instead, the bound was far above a path through open space (the
    warehouse map's end-to-end search reached twice the cells it needed) and below one that winds. Measured on
    random start and goal pairs: within a few per cent on the warehouse map, 10-40 % under on the bench map,
    whose scattered obstacles the blocks smooth away; so a quarter is added, and a search that falls short
    doubles its bound as before.
    """
    k = COARSE_BLOCK
    rows, cols = cost.shape
    b_rows, b_cols = -(-rows // k), -(-cols // k)
    cells = np.full((b_rows * k, b_cols * k), NO_INFORMATION, dtype=np.uint8)
    inner = cells[:rows, :cols]
    np.minimum(cost, MAX_NON_OBSTACLE, out=inner)
    np.copyto(inner, NO_INFORMATION, where=~passable)
    # Each block's cheapest cell: the minimum of the k*k strided views, one per position in the block (a minimum
    # over two axes of the reshaped grid walks it in small strides, six times slower on a 400x400 grid).
    blocks = cells[::k, ::k].copy()
    for i in range(k):
        for j in range(k):
            if i or j:
                np.minimum(blocks, cells[i::k, j::k], out=blocks)
    s, g = (start[0] // k, start[1] // k), (goal[0] // k, goal[1] // k)
    if s == g:
        return 0.0
    res = resolution_m * k
    h = _potential(blocks.shape, g, res, params)
    graph = _graph(edge_weights(blocks, blocks <= MAX_NON_OBSTACLE, res, params, h), blocks.shape)
    h_start = float(h[s])
    found = _bounded_search(graph, s[0] * b_cols + s[1], g[0] * b_cols + g[1],
                            _share_of_straight(h_start, res, "astar"))
    return None if found is None else found[0] + h_start


def _potential(shape: tuple[int, int], goal: tuple[int, int], resolution_m: float, params: PlannerParams
               ) -> FloatArray:
    """A*'s heuristic in every cell: the octile distance to ``goal`` at the cheapest cost per metre (rows and
    columns broadcast: the numbers np.indices gives, in one pass)."""
    rows, cols = shape
    return octile_m(np.arange(rows)[:, None], np.arange(cols)[None, :], goal, resolution_m) * params.neutral_cost


def _graph(weights: NDArray[np.float64], shape: tuple[int, int]) -> csr_matrix:
    """The grid's 8-neighbour graph with these (N, 8) weights, on the structure cached for its shape."""
    indptr, indices = _structure(*shape)
    n = shape[0] * shape[1]
    return csr_matrix((weights.reshape(-1), indices, indptr), shape=(n, n))


def _share_of_straight(straight: float, resolution_m: float, algorithm: Algorithm) -> float:
    """A first bound from the straight line's cost alone: for A* (a bound on the cost above the heuristic) three
    quarters of it, as indoor paths with their obstacle costs mostly cost less than 1.75 times the straight line;
    for Dijkstra (a bound on the cost itself) 1.75 times it."""
    return (0.75 if algorithm == "astar" else 1.75) * straight + 10 * resolution_m


def _bounded_search(graph: csr_matrix, s_flat: int, g_flat: int, limit: float, first: float | None = None
                    ) -> tuple[float, NDArray[np.int32], FloatArray, int] | None:
    """Dijkstra from ``s_flat`` with its cost bound ``limit`` doubled until the goal is reached: the (reduced)
    cost to the goal, the predecessors, the (reduced) distances and how many cells were reached in all; None
    when the goal stays out of reach (only through lethal cells, or nothing more is reached). A ``first`` bound
    below ``limit`` (a known cost) is tried before."""
    expanded = 0
    if first is not None and first < limit:
        dist, pred = dijkstra(graph, indices=s_flat, return_predecessors=True, limit=first)
        d_goal = float(dist[g_flat])
        expanded += int(np.count_nonzero(np.isfinite(dist) & (dist < _BLOCKED / 10)))
        if d_goal < _BLOCKED / 10:
            return d_goal, pred, dist, expanded
    reached_before = -1
    while True:
        dist, pred = dijkstra(graph, indices=s_flat, return_predecessors=True, limit=limit)
        d_goal = float(dist[g_flat])
        reached = int(np.count_nonzero(np.isfinite(dist) & (dist < _BLOCKED / 10)))
        expanded += reached
        if math.isfinite(d_goal):
            return None if d_goal >= _BLOCKED / 10 else (d_goal, pred, dist, expanded)
        if reached == reached_before or not math.isfinite(limit):
            return None
        reached_before = reached
        limit = limit * 2 if limit < 1e6 else math.inf


def _walk_back(pred: NDArray[np.int32], start: int, goal: int) -> NDArray[np.intp]:
    out = [goal]
    node = goal
    limit = pred.shape[0]
    links = pred.data  # a memoryview: Python ints, without a numpy scalar per step
    while node != start:
        node = links[node]
        if node < 0 or len(out) > limit:
            raise NavigationError("planner: broken predecessor chain (internal error)")
        out.append(node)
    return np.array(out[::-1], dtype=np.intp)


def smooth_path(points: FloatArray, costmap: Costmap, *, window: int = 80, spacing_m: float = 0.05,
                iterations: int = 30) -> FloatArray:
    """Shortcut by line of sight, then relax gently; never onto or through inscribed/lethal cells.

    A shortcut from point i to the farthest j is accepted only when no cell along it costs more than the
    costliest cell of the grid path it replaces, so the shortcut is never closer to an obstacle than the
    planned path was. The relaxation (a few steps of the classic data/smoothness gradient) moves only
    interior points and rolls back any point that would land in a costlier cell than it left.
    """
    if len(points) <= 2:
        return points.copy()
    cost = costmap.cost_at(points[:, 0], points[:, 1]).astype(np.int32)
    keep = [0]
    i = 0
    n = len(points)
    while i < n - 1:
        j = np.arange(i + 1, min(i + window, n - 1) + 1)
        run_max = np.maximum.accumulate(cost[i + 1: j[-1] + 1])
        ok = _segment_costs_within(costmap, points[i], points[j], run_max)
        good = np.nonzero(ok)[0]
        nxt = int(j[good[-1]]) if len(good) else i + 1
        keep.append(nxt)
        i = nxt
    short = points[keep]
    dense = resample(short, spacing_m)
    if len(dense) <= 2:
        return dense
    path = dense.copy()
    base_cost = costmap.cost_at(path[:, 0], path[:, 1]).astype(np.int32)
    for _ in range(iterations):
        cand = path.copy()
        cand[1:-1] += 0.1 * (dense[1:-1] - path[1:-1]) + 0.3 * (path[:-2] + path[2:] - 2 * path[1:-1])
        c = costmap.cost_at(cand[:, 0], cand[:, 1]).astype(np.int32)
        accept = (c <= base_cost) & (c < INSCRIBED)
        path = np.where(accept[:, None], cand, path)
    return path


def _segment_costs_within(costmap: Costmap, a: FloatArray, ends: FloatArray, run_max: NDArray[np.int32]
                          ) -> NDArray[np.bool_]:
    """Per candidate end j: no cell sampled (each half cell) along the segment a→ends[j] costs more than the
    grid path's maximum up to j. All candidates and samples at once."""
    length = np.hypot(ends[:, 0] - a[0], ends[:, 1] - a[1])
    n = int(length.max() / (costmap.resolution_m / 2)) + 2
    t = np.linspace(0.0, 1.0, n)
    x = a[0] + (ends[:, 0:1] - a[0]) * t[None, :]
    y = a[1] + (ends[:, 1:2] - a[1]) * t[None, :]
    c = costmap.cost_at(x, y).astype(np.int32).max(axis=1)
    ok: NDArray[np.bool_] = c <= run_max[: len(ends)]
    return ok


def resample(points: FloatArray, spacing_m: float) -> FloatArray:
    """Points along the polyline every ``spacing_m`` (keeping both ends)."""
    if len(points) < 2:
        return points.copy()
    seg = np.hypot(*np.diff(points, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s[-1])
    if total <= 0:
        return points[[0, -1]].copy()
    m = max(math.ceil(total / spacing_m), 1)
    q = np.linspace(0.0, total, m + 1)
    return np.column_stack([np.interp(q, s, points[:, 0]), np.interp(q, s, points[:, 1])])
