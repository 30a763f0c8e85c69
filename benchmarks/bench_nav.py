"""Navigation speed: A* on a 400x400 costmap against a textbook heapq A*, and the per-tick costs.

Rows (``python benchmarks/bench_nav.py``):

* A* (``atemr.skills.nav.global_planner``: Dijkstra on heuristic-reduced costs in scipy's compiled
  Dijkstra, growing f-bound) on a 400x400 costmap with rooms, walls and random clutter, corner to corner,
  against the textbook A* below (heapq, dict/set bookkeeping, the same 8-connected cost-aware edges and
  the same octile heuristic) on the same costmap and the same start/goal; both answers' costs are checked
  to agree. Goal >= 10x.
* Dijkstra (same planner, ``algorithm="dijkstra"``) against the same textbook A* (informational).
* A* replanning after each scan (the planner keeps its edge weights and patches them where the costmap
  changed, as in the navigator) against the same baseline (informational).
* one costmap update from a 360-beam scan (clear + mark + inflate), updates per second (goal >= 10 Hz,
  the lidar's rate).
* the obstacle layer's clearing, compiled (``_clear_beams``), against the numpy version it replaced
  (``numpy_baselines.py``: every beam's samples at once), on a 400x400 map whose layer holds marks: the same
  cells, updates per second, interleaved. Goal >= 1x.
* one local-planner tick (dynamic window, all (v, w) samples and time steps at once), ticks per second
  (goal >= 10 Hz); and the same tick with its rollouts and safety checks compiled (``_rollout_poses``,
  ``_rollouts_valid``) against the numpy versions they replaced (``numpy_baselines.NumpyLocalPlanner``): the
  same plan, interleaved. Goal >= 1x.
* A* against tcod (libtcod's C pathfinder, a benchmark-only dependency: the ``bench`` extra) on the same cost
  model: 8-connected, entering a cell costs its step length times ``1 + 3 · cost/252`` (tcod in integers:
  cell cost ``84 + cost`` times 1000 or 1414 per step, so its diagonals are 0.0015 % short), no corner cutting
  (a condition per diagonal edge), octile heuristic. On the bench map and on a large real map (nav2's
  warehouse, 1674 x 1006 cells, from ``../shared/worlds/external``; skipped when absent). Cold: a new planner
  (ours builds every edge weight; tcod builds its graph) for each plan. Warm: the same start and goal again
  with the graph kept (ours: cached weights and the last path's cost to go; tcod: its graph, a new search).
  Each row gives both paths' costs under our model. Median CPU time of interleaved trials. Goal >= 1x.
"""

from __future__ import annotations

import heapq
import math
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from bench_sim import interleaved_ms
from numpy.typing import NDArray
from numpy_baselines import NumpyClearingCostmap, NumpyLocalPlanner

from atemr.domain.maps import OccupancyMap
from atemr.msgs import LaserScan, Pose2D, Twist
from atemr.skills.nav.costmap import INSCRIBED, MAX_NON_OBSTACLE, Costmap
from atemr.skills.nav.global_planner import GlobalPlanner, PlannerParams
from atemr.skills.nav.local_planner import LocalPlanner

LARGE_MAP = Path(__file__).resolve().parents[2] / "shared" / "worlds" / "external" / "nav2_warehouse.yaml"


def make_grid(size: int = 400, seed: int = 7) -> OccupancyMap:
    """A 20 m x 20 m building at 5 cm: a 4x4 block of rooms with doorways and random boxes inside."""
    rng = np.random.default_rng(seed)
    data = np.zeros((size, size), dtype=np.int8)
    data[:3, :] = data[-3:, :] = data[:, :3] = data[:, -3:] = 100
    room = size // 4
    for k in range(1, 4):
        data[k * room - 1:k * room + 2, :] = 100
        data[:, k * room - 1:k * room + 2] = 100
    for a in range(4):
        for k in range(1, 4):
            mid = a * room + room // 2 + int(rng.integers(-room // 4, room // 4))
            data[k * room - 1:k * room + 2, mid - 9:mid + 9] = 0  # doorway 0.9 m
            mid = a * room + room // 2 + int(rng.integers(-room // 4, room // 4))
            data[mid - 9:mid + 9, k * room - 1:k * room + 2] = 0
    for _ in range(60):
        r, c = (int(v) for v in rng.integers(10, size - 20, 2))
        h, w = (int(v) for v in rng.integers(4, 14, 2))
        data[r:r + h, c:c + w] = 100
    return OccupancyMap(data, 0.05, Pose2D(0.0, 0.0, 0.0), name="bench400")


def textbook_astar(cost: NDArray[np.uint8], start: tuple[int, int], goal: tuple[int, int], *, resolution_m: float,
                   neutral: float, factor: float) -> float:
    """The baseline: A* as in a textbook (heapq open list, dicts for g and parents, closed set), with the
    planner's edge cost (entering cell c costs length · (neutral + factor · cost/252)), its corner rule and
    its octile heuristic. Returns the path cost (inf: no path)."""
    rows, cols = cost.shape
    grid = cost.tolist()
    moves = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]

    def passable(r: int, c: int) -> bool:
        return 0 <= r < rows and 0 <= c < cols and grid[r][c] < INSCRIBED

    def h(r: int, c: int) -> float:
        dr, dc = abs(r - goal[0]), abs(c - goal[1])
        return (max(dr, dc) + (math.sqrt(2) - 1) * min(dr, dc)) * resolution_m * neutral

    g_score = {start: 0.0}
    parent: dict[tuple[int, int], tuple[int, int]] = {}
    closed: set[tuple[int, int]] = set()
    open_heap = [(h(*start), start)]
    while open_heap:
        _, node = heapq.heappop(open_heap)
        if node in closed:
            continue
        if node == goal:
            return g_score[node]
        closed.add(node)
        r, c = node
        for dr, dc in moves:
            nr, nc = r + dr, c + dc
            if not passable(nr, nc) or (nr, nc) in closed:
                continue
            if dr and dc and not (passable(r + dr, c) and passable(r, c + dc)):
                continue
            step = math.hypot(dr, dc) * resolution_m
            g = g_score[node] + step * (neutral + factor * min(grid[nr][nc], MAX_NON_OBSTACLE) / MAX_NON_OBSTACLE)
            if g < g_score.get((nr, nc), math.inf):
                g_score[(nr, nc)] = g
                parent[(nr, nc)] = node
                heapq.heappush(open_heap, (g + h(nr, nc), (nr, nc)))
    return math.inf


def clearing_row(occ: OccupancyMap, scan: LaserScan, pose: Pose2D, repeats: int) -> dict[str, Any]:
    """A scan's update of the obstacle layer (marks in it, so the beams clear), the compiled clearing against the
    numpy one it replaced, interleaved best-of; the layers must come out the same."""
    maps = {"ours": Costmap(occ), "numpy": NumpyClearingCostmap(occ)}
    marks = np.random.default_rng(2).random(occ.data.shape) < 0.02
    best = dict.fromkeys(maps, math.inf)
    for _ in range(repeats):
        for name, cm in maps.items():
            cm.obstacles[:] = marks
            t, _ = _best(lambda cm=cm: cm.update_from_scan(scan, pose), 1)
            best[name] = min(best[name], t)
    assert np.array_equal(maps["ours"].obstacles, maps["numpy"].obstacles)
    return {"what": "  the layer's clearing compiled vs the numpy one it replaced (same cells)",
            "ours": round(1.0 / best["ours"], 1), "baseline": round(1.0 / best["numpy"], 1),
            "ratio": round(best["numpy"] / best["ours"], 2), "goal": 1.0, "unit": "updates/s"}


def local_planner_row(cm: Costmap, pose: Pose2D, path: Any, goal_xy: tuple[float, float],
                      repeats: int) -> dict[str, Any]:
    """A local-planner tick with the compiled rollouts and checks against the numpy ones they replaced,
    interleaved (`bench_sim.interleaved_ms`); the plans must be the same."""
    ours, base = LocalPlanner(cm), NumpyLocalPlanner(cm)
    call = (pose, Twist(0.3, 0.0), path, goal_xy)
    if ours.compute(*call).twist != base.compute(*call).twist:
        raise AssertionError("the compiled rollouts and checks chose another plan than the numpy ones")
    ours_ms, base_ms = interleaved_ms(ours.compute, base.compute, [call] * repeats)
    return {"what": "  the tick's rollouts and checks compiled vs the numpy ones they replaced (same plan)",
            "ours": round(1e3 / ours_ms, 1), "baseline": round(1e3 / base_ms, 1),
            "ratio": round(base_ms / ours_ms, 2), "goal": 1.0, "unit": "ticks/s"}


def _best(fn: Any, repeats: int) -> tuple[float, Any]:
    best = math.inf
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def run(quick: bool = False) -> list[dict[str, Any]]:  # noqa: PLR0915  the benchmark's rows measured in order, one block each
    rows: list[dict[str, Any]] = []
    occ = make_grid()
    cm = Costmap(occ)
    _ = cm.cost
    start_xy, goal_xy = (0.5, 0.5), (19.4, 19.3)
    s = tuple(int(v) for v in cm.cells(*start_xy)[:2])
    g = tuple(int(v) for v in cm.cells(*goal_xy)[:2])
    repeats = 1 if quick else 3
    params = PlannerParams(smooth=False)

    def baseline() -> float:
        return textbook_astar(cm.cost, s, g, resolution_m=cm.resolution_m,  # type: ignore[arg-type]
                              neutral=params.neutral_cost, factor=params.cost_factor)

    # Interleaved (baseline, ours, ours, ...) and best-of for each, so a busy machine hurts both alike.
    t_base = math.inf
    t_ours = {"astar": math.inf, "dijkstra": math.inf}
    paths: dict[str, Any] = {}
    base_cost = math.inf
    for _ in range(repeats):
        tb, base_cost = _best(baseline, 1)
        t_base = min(t_base, tb)
        for algorithm in ("astar", "dijkstra"):
            p = PlannerParams(algorithm=algorithm, smooth=False)
            # A new planner each time: every edge weight is built, as for a first plan.
            t, paths[algorithm] = _best(lambda p=p: GlobalPlanner(cm, p).plan(start_xy, goal_xy), 2)
            t_ours[algorithm] = min(t_ours[algorithm], t)
    for algorithm in ("astar", "dijkstra"):
        path = paths[algorithm]
        assert path is not None and abs(path.cost - base_cost) < 1e-6 * max(base_cost, 1.0), (path, base_cost)
        rows.append({"what": f"{algorithm} 400x400 costmap, corner to corner ({path.expanded} cells reached)",
                     "ours": round(1.0 / t_ours[algorithm], 2), "baseline": round(1.0 / t_base, 2),
                     "ratio": round(t_base / t_ours[algorithm], 1), "goal": 10.0 if algorithm == "astar" else None,
                     "unit": "plans/s"})

    # Replanning after a scan: the planner keeps its edge weights and patches them where the costmap changed.
    planner = GlobalPlanner(cm, PlannerParams(smooth=False))
    planner.plan(start_xy, goal_xy)
    scans = [LaserScan(float(k), np.random.default_rng(k).uniform(0.5, 4.0, 360), -math.pi, 2 * math.pi / 360,
                       0.15, 8.0, Pose2D(0.1, 0.0, 0.0)) for k in range(8)]
    where = Pose2D(10.0, 10.0, 0.0)

    def replan(k: list[int] = [0]) -> Any:  # noqa: B006 - a counter across calls
        cm.update_from_scan(scans[k[0] % len(scans)], where)
        k[0] += 1
        return planner.plan(start_xy, goal_xy)

    t_replan, _ = _best(replan, repeats + 2)
    rows.append({"what": "A* replan after a scan (cached weights patched), 400x400, corner to corner",
                 "ours": round(1.0 / t_replan, 2), "baseline": round(1.0 / t_base, 2),
                 "ratio": round(t_base / t_replan, 1), "goal": None, "unit": "plans/s"})
    cm.clear_obstacles()

    # Costmap update from a scan (studio-like clutter around the robot).
    pose = Pose2D(5.0, 5.0, 0.3)
    beams = 360
    rng = np.random.default_rng(1)
    scan = LaserScan(0.0, rng.uniform(0.5, 6.0, beams), -math.pi, 2 * math.pi / beams, 0.15, 8.0,
                     Pose2D(0.1, 0.0, 0.0))

    def update() -> None:
        cm.update_from_scan(scan, pose)
        _ = cm.cost

    t_update, _ = _best(update, 5 if quick else 20)
    rows.append({"what": "costmap update from a 360-beam scan (clear, mark, inflate), 400x400",
                 "ours": round(1.0 / t_update, 1), "baseline": 10.0, "ratio": round(0.1 / t_update, 1),
                 "goal": 1.0, "unit": "updates/s (baseline: the lidar's 10 Hz)"})
    rows.append(clearing_row(occ, scan, pose, 5 if quick else 20))

    cm.clear_obstacles()
    free_rows, free_cols = np.nonzero(cm.cost == 0)
    fx, fy = cm.map.cell_to_world(free_rows, free_cols)
    start = int(np.argmin(np.hypot(fx - 5.0, fy - 5.0)))
    goal = int(np.argmin(np.hypot(fx - 8.0, fy - 7.0)))
    pose = Pose2D(float(fx[start]), float(fy[start]), 0.3)
    goal_xy = (float(fx[goal]), float(fy[goal]))
    path = GlobalPlanner(cm).plan((pose.x_m, pose.y_m), goal_xy)
    assert path is not None
    local = LocalPlanner(cm)
    t_local, _ = _best(lambda: local.compute(pose, Twist(0.3, 0.0), path.points, goal_xy), 5 if quick else 30)
    rows.append({"what": "local planner tick (dynamic window, all samples x steps at once)",
                 "ours": round(1.0 / t_local, 1), "baseline": 10.0, "ratio": round(0.1 / t_local, 1),
                 "goal": 1.0, "unit": "ticks/s (baseline: the 10 Hz control rate)"})
    rows.append(local_planner_row(cm, pose, path.points, goal_xy, 10 if quick else 30))
    return rows + against_tcod(quick)


def against_tcod(quick: bool = False) -> list[dict[str, Any]]:
    """A* against tcod, cold and warm, on the bench map and the large map (see the module docstring)."""
    try:
        import tcod  # noqa: F401  (the bench extra)
    except ImportError:
        return [_skipped("A* vs tcod: skipped, tcod is not installed (pip install atemr[bench])")]
    cm = Costmap(make_grid())
    cases = [("400x400 bench costmap, corner to corner", cm, cm.cells(0.5, 0.5)[:2], cm.cells(19.4, 19.3)[:2])]
    if LARGE_MAP.is_file():
        from atemr.io.sim.world import load_world

        big = Costmap(load_world(str(LARGE_MAP)).map)
        free = np.argwhere(big.cost == 0)

        def nearest(row_frac: float, col_frac: float) -> tuple[int, int]:
            target = np.array([row_frac * big.shape[0], col_frac * big.shape[1]])
            return tuple(int(v) for v in free[np.argmin(((free - target) ** 2).sum(axis=1))])  # type: ignore[return-value]

        cases.append((f"{big.shape[0]}x{big.shape[1]} warehouse map (nav2), end to end", big, nearest(0.05, 0.1),
                      nearest(0.95, 0.85)))
    rows = [] if LARGE_MAP.is_file() else [_skipped(f"A* vs tcod on a large map: skipped, {LARGE_MAP} is absent")]
    for label, costmap, start, goal in cases:
        rows += _astar_vs_tcod(label, costmap, (int(start[0]), int(start[1])), (int(goal[0]), int(goal[1])),
                               5 if quick else 9)
    return rows


def tcod_graph(cost: NDArray[np.uint8], passable: NDArray[np.bool_]) -> Any:
    """tcod's graph for the planner's cost model, in integers (see the module docstring)."""
    import tcod

    per_cell = np.where(passable, 84 + np.minimum(cost, MAX_NON_OBSTACLE).astype(np.int32), 0).astype(np.int32)
    graph = tcod.path.CustomGraph(cost.shape)
    pad = np.pad(passable, 1)
    rows, cols = cost.shape
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr and dc:  # no corner cutting: both cells passed between must be passable
                beside = pad[1 + dr:1 + dr + rows, 1:1 + cols] & pad[1:1 + rows, 1 + dc:1 + dc + cols]
                graph.add_edge((dr, dc), 1414, cost=per_cell, condition=beside.astype(np.int8))
            elif dr or dc:
                graph.add_edge((dr, dc), 1000, cost=per_cell)
    graph.set_heuristic(cardinal=84 * 1000, diagonal=84 * 1414)
    return graph


def cost_of_cells(cells: NDArray[Any], cost: NDArray[np.uint8], resolution_m: float) -> float:
    """A grid path's cost under the planner's model: the step length into each cell times its cost per metre."""
    per_m = 1.0 + 3.0 * np.minimum(cost, MAX_NON_OBSTACLE) / MAX_NON_OBSTACLE
    steps = np.diff(cells, axis=0)
    return float((np.hypot(steps[:, 0], steps[:, 1]) * resolution_m * per_m[cells[1:, 0], cells[1:, 1]]).sum())


def _astar_vs_tcod(label: str, cm: Costmap, start: tuple[int, int], goal: tuple[int, int], trials: int
                   ) -> list[dict[str, Any]]:
    import tcod

    cost, passable = cm.cost, cm.traversable(allow_unknown=False)
    start_xy = tuple(float(v) for v in cm.map.cell_to_world(*start))
    goal_xy = tuple(float(v) for v in cm.map.cell_to_world(*goal))
    params = PlannerParams(smooth=False)
    warm = GlobalPlanner(cm, params)
    warm.plan(start_xy, goal_xy)  # type: ignore[arg-type]
    kept = tcod_graph(cost, passable)

    def theirs(graph: Any) -> NDArray[Any]:
        finder = tcod.path.Pathfinder(graph)
        finder.add_root(start)
        return np.asarray(finder.path_to(goal))

    runs: dict[str, Callable[[], Any]] = {
        "ours cold": lambda: GlobalPlanner(cm, params).plan(start_xy, goal_xy),  # type: ignore[arg-type]
        "tcod cold": lambda: theirs(tcod_graph(cost, passable)),
        "ours warm": lambda: warm.plan(start_xy, goal_xy),  # type: ignore[arg-type]
        "tcod warm": lambda: theirs(kept),
    }
    times: dict[str, list[float]] = {k: [] for k in runs}
    for _ in range(trials):
        for name, run_once in runs.items():
            t0 = time.thread_time()
            run_once()
            times[name].append(time.thread_time() - t0)
    median = {k: statistics.median(v) for k, v in times.items()}
    tcod_cost = cost_of_cells(runs["tcod cold"](), cost, cm.resolution_m)
    rows = []
    for mode in ("cold", "warm"):
        ours_path = runs[f"ours {mode}"]()
        rows.append({
            "what": f"A* {mode} vs tcod, {label} (path cost {ours_path.cost:.3f} vs {tcod_cost:.3f}; "
                    f"{ours_path.expanded} cells reached)",
            "ours": round(1.0 / median[f"ours {mode}"], 2), "baseline": round(1.0 / median[f"tcod {mode}"], 2),
            "ratio": round(median[f"tcod {mode}"] / median[f"ours {mode}"], 2), "goal": 1.0, "unit": "plans/s",
        })
    return rows


def _skipped(what: str) -> dict[str, Any]:
    return {"what": what, "ours": None, "baseline": None, "ratio": None, "goal": None, "unit": ""}


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)
