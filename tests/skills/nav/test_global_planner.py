import heapq
import math
from types import ModuleType

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.skills.nav.costmap import INSCRIBED, Costmap, CostmapParams
from atemr.skills.nav.global_planner import GlobalPlanner, PlannerParams, coarse_cost, resample

RES = 0.05


def reference_cost(cost, start, goal, factor, neutral=1.0):
    """Plain heapq Dijkstra with the planner's edge rule (entering cell c costs len * (1 + f c/252), no
    corner cutting): the known answer to compare with."""
    rows, cols = cost.shape
    ok = cost < INSCRIBED
    dist = {start: 0.0}
    heap = [(0.0, start)]
    while heap:
        d, (r, c) = heapq.heappop(heap)
        if (r, c) == goal:
            return d
        if d > dist[(r, c)]:
            continue
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                nr, nc = r + dr, c + dc
                if (dr, dc) == (0, 0) or not (0 <= nr < rows and 0 <= nc < cols) or not ok[nr, nc]:
                    continue
                if dr and dc and not (ok[r + dr, c] and ok[r, c + dc]):
                    continue
                nd = d + math.hypot(dr, dc) * RES * (neutral + factor * min(int(cost[nr, nc]), 252) / 252)
                if nd < dist.get((nr, nc), math.inf):
                    dist[(nr, nc)] = nd
                    heapq.heappush(heap, (nd, (nr, nc)))
    return math.inf


def centre(cm, row, col):
    x, y = cm.map.cell_to_world(row, col)
    return float(x), float(y)


@pytest.mark.parametrize("algorithm", ["astar", "dijkstra"])
def test_empty_grid_shortest_path_is_the_octile_distance(make_map, algorithm):
    cm = Costmap(make_map(np.zeros((30, 40), dtype=np.int8), RES))
    planner = GlobalPlanner(cm, PlannerParams(algorithm=algorithm, smooth=False))
    path = planner.plan(centre(cm, 2, 3), centre(cm, 12, 28))
    assert path is not None
    # 10 diagonal steps + 15 straight ones.
    assert path.cost == pytest.approx((10 * math.sqrt(2) + 15) * RES, rel=1e-9)
    assert path.length_m == pytest.approx(path.cost, rel=1e-9)
    assert len(path.cells) == 26


@pytest.mark.parametrize("seed", range(4))
def test_astar_and_dijkstra_agree_with_a_reference_search(make_map, seed):
    rng = np.random.default_rng(seed)
    data = np.zeros((50, 60), dtype=np.int8)
    for _ in range(12):
        r, c = rng.integers(0, 45), rng.integers(0, 55)
        data[r:r + rng.integers(1, 6), c:c + rng.integers(1, 6)] = 100
    cm = Costmap(make_map(data, RES), CostmapParams(robot_radius_m=0.05, footprint_padding_m=0.0,
                                                     inflation_radius_m=0.3))
    free = np.argwhere(cm.cost < INSCRIBED)
    s, g = free[rng.integers(len(free))], free[rng.integers(len(free))]
    want = reference_cost(cm.cost, tuple(s), tuple(g), factor=3.0)
    for algorithm in ("astar", "dijkstra"):
        path = GlobalPlanner(cm, PlannerParams(algorithm=algorithm, smooth=False)).plan(centre(cm, *s), centre(cm, *g))
        if math.isinf(want):
            assert path is None
        else:
            assert path is not None
            assert path.cost == pytest.approx(want, rel=1e-9)


def test_astar_expands_fewer_cells_than_dijkstra_in_the_open(make_map):
    cm = Costmap(make_map(np.zeros((200, 200), dtype=np.int8), RES))
    a = GlobalPlanner(cm, PlannerParams(algorithm="astar", smooth=False)).plan(centre(cm, 100, 10), centre(cm, 100, 60))
    d = GlobalPlanner(cm, PlannerParams(algorithm="dijkstra", smooth=False)).plan(centre(cm, 100, 10),
                                                                                   centre(cm, 100, 60))
    assert a is not None and d is not None
    assert a.cost == pytest.approx(d.cost)
    assert a.expanded < 0.75 * d.expanded


def corridor(make_map, blocked):
    """Two rooms joined by a 0.9 m corridor; ``blocked`` closes it with a wall."""
    data = np.full((60, 120), 100, dtype=np.int8)
    data[1:-1, 1:45] = 0
    data[1:-1, 75:-1] = 0
    data[21:39, 45:75] = 0  # corridor 18 cells = 0.9 m
    if blocked:
        data[21:39, 60] = 100
    return Costmap(make_map(data, RES))


def test_path_goes_through_the_corridor(make_map):
    cm = corridor(make_map, blocked=False)
    path = GlobalPlanner(cm).plan((0.5, 1.5), (5.5, 1.5))
    assert path is not None
    on_corridor = (path.points[:, 0] > 2.3) & (path.points[:, 0] < 3.7)
    assert on_corridor.any()
    assert (np.abs(path.points[on_corridor, 1] - 1.5) < 0.1).all()  # the corridor's middle (cheapest)


def test_blocked_corridor_has_no_path(make_map):
    cm = corridor(make_map, blocked=True)
    for algorithm in ("astar", "dijkstra"):
        assert GlobalPlanner(cm, PlannerParams(algorithm=algorithm)).plan((0.5, 1.5), (5.5, 1.5)) is None


def test_goal_in_an_obstacle_or_inscribed_zone_has_no_path(make_map, make_room):
    data = make_room(40, 40)
    data[20, 20] = 100
    cm = Costmap(make_map(data, RES))
    planner = GlobalPlanner(cm)
    assert planner.plan((0.5, 0.5), centre(cm, 20, 20)) is None
    assert planner.plan((0.5, 0.5), centre(cm, 20, 23)) is None


def test_bad_coordinates_are_navigation_errors(make_map, make_room):
    planner = GlobalPlanner(Costmap(make_map(make_room(), RES)))
    with pytest.raises(NavigationError, match="finite"):
        planner.plan((float("nan"), 1.0), (1.0, 1.0))
    with pytest.raises(NavigationError, match="outside the map"):
        planner.plan((1.0, 1.0), (50.0, 1.0))


def test_start_pressed_against_a_wall_can_still_plan_out(make_map, make_room):
    cm = Costmap(make_map(make_room(60, 80), RES))
    start = (0.2, 1.5)  # 0.15 m from the wall's cell centre: inside the inscribed zone
    assert cm.cost_at(*start) == INSCRIBED
    path = GlobalPlanner(cm).plan(start, (3.0, 1.5))
    assert path is not None


def test_smoothed_path_is_shorter_and_never_enters_the_inscribed_zone(make_map):
    rng = np.random.default_rng(3)
    data = np.zeros((120, 160), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    for _ in range(25):
        r, c = rng.integers(5, 110), rng.integers(5, 150)
        data[r:r + 6, c:c + 6] = 100
    cm = Costmap(make_map(data, RES))
    raw = GlobalPlanner(cm, PlannerParams(smooth=False)).plan((0.5, 0.5), (7.5, 5.5))
    smooth = GlobalPlanner(cm).plan((0.5, 0.5), (7.5, 5.5))
    assert raw is not None and smooth is not None
    assert smooth.length_m < raw.length_m
    dense = resample(smooth.points, 0.01)
    assert (cm.cost_at(dense[:, 0], dense[:, 1]) < INSCRIBED).all()
    assert np.allclose(smooth.points[0], (0.5, 0.5)) and np.allclose(smooth.points[-1], (7.5, 5.5))


def test_cached_weights_patched_after_a_scan_equal_a_full_rebuild(make_map):
    from atemr.msgs import LaserScan, Pose2D
    from atemr.skills.nav.global_planner import edge_weights

    rng = np.random.default_rng(5)
    cm = Costmap(make_map(np.zeros((80, 100), dtype=np.int8), RES))
    planner = GlobalPlanner(cm)
    assert planner.plan((0.5, 0.5), (4.5, 3.5)) is not None
    for k in range(3):
        ranges = rng.uniform(0.5, 2.0, 90)
        cm.update_from_scan(LaserScan(float(k), ranges, -math.pi, 2 * math.pi / 90, 0.15, 8.0), Pose2D(2.5, 2.0, 0.0))
        fresh = GlobalPlanner(cm).plan((0.5, 0.5), (4.5, 3.5))
        cached = planner.plan((0.5, 0.5), (4.5, 3.5))
        assert (fresh is None) == (cached is None)
        if fresh is not None and cached is not None:
            assert cached.cost == pytest.approx(fresh.cost, rel=1e-12)
        full = edge_weights(cm.cost, cm.traversable(), RES, planner.params)
        assert np.array_equal(planner._weights(cm.cost, cm.traversable(), None, (0, 0)), full)


def test_a_replan_to_the_same_goal_searches_only_as_far_as_the_last_path_costs(make_map):
    """A replan from a cell of the last path searches with that path's cost to go as its bound: the same path as
    a new planner finds, from fewer cells. After a scan changes the costmap on the path the bound no longer
    holds and is not used; off the path it still is. Either way the answer is a new planner's."""
    from atemr.msgs import LaserScan, Pose2D

    rng = np.random.default_rng(3)
    data = np.zeros((80, 100), dtype=np.int8)
    data[20:60, 45:50] = 100  # a wall to go round
    cm = Costmap(make_map(data, RES))
    planner = GlobalPlanner(cm, PlannerParams(smooth=False))
    goal = (4.5, 3.5)
    first = planner.plan((0.5, 0.5), goal)
    assert first is not None
    for k, where in enumerate([None, (1.0, 3.5), (3.5, 0.5)]):  # unchanged; a scan far from the path; one on it
        if where is not None:
            ranges = rng.uniform(0.3, 0.6, 90)
            cm.update_from_scan(LaserScan(float(k), ranges, -math.pi, 2 * math.pi / 90, 0.15, 8.0), Pose2D(*where, 0.0))
        start = centre(cm, *divmod(int(first.cells[len(first.cells) // 4]), cm.shape[1]))
        fresh = GlobalPlanner(cm, PlannerParams(smooth=False)).plan(start, goal)
        replan = planner.plan(start, goal)
        assert fresh is not None and replan is not None
        assert np.array_equal(replan.cells, fresh.cells) and replan.cost == fresh.cost
        if k < 2:  # the bound held: far fewer cells reached (about a fifth here)
            assert replan.expanded < fresh.expanded / 2


def test_the_first_bound_from_a_coarse_plan_reaches_few_more_cells_than_the_exact_bound(make_map):
    """A* takes its first bound from a plan on a grid four times coarser: round a long wall in an open hall a new
    plan reaches 1.3 times the cells of a replan bounded by the exact cost to go (with three quarters of the
    straight line, its bound before, 2.1 times), and finds the same path."""
    data = np.zeros((200, 600), dtype=np.int8)
    data[20:180, 300:303] = 100  # a wall across the hall, to go round at either end
    cm = Costmap(make_map(data, RES))
    start, goal = centre(cm, 100, 5), centre(cm, 60, 595)
    planner = GlobalPlanner(cm, PlannerParams(smooth=False))
    cold = planner.plan(start, goal)
    exact = planner.plan(start, goal)  # a replan: bounded by the cost to go it just found
    assert cold is not None and exact is not None
    assert np.array_equal(cold.cells, exact.cells) and cold.cost == exact.cost
    assert cold.expanded < 1.5 * exact.expanded, (cold.expanded, exact.expanded)


@pytest.mark.parametrize(("seed", "allow_unknown"), [(0, False), (1, False), (2, True), (3, True)])
def test_the_coarse_plan_estimates_the_path_cost_and_knows_when_there_is_none(make_map, seed, allow_unknown):
    """Against Dijkstra on the full grid (which never asks the coarse grid): "no path" exactly when it has none,
    otherwise a cost within a fifth of its path's. Rooms behind walls, one of them closed for good, clutter and
    unknown patches, on a grid whose sides are not multiples of the block."""
    rng = np.random.default_rng(seed)
    data = np.zeros((122, 158), dtype=np.int8)
    for _ in range(25):
        r, c = rng.integers(0, 110), rng.integers(0, 150)
        data[r:r + rng.integers(2, 12), c:c + rng.integers(2, 12)] = 100
    for _ in range(4):
        r, c = rng.integers(0, 110), rng.integers(0, 150)
        data[r:r + rng.integers(3, 10), c:c + rng.integers(3, 10)] = -1
    for col, door in ((50, True), (100, False)):  # a wall with a door; a wall closed for good
        data[:, col:col + 2] = 100
        if door:
            row = int(rng.integers(10, 100))
            data[row:row + 14, col:col + 2] = 0
    cm = Costmap(make_map(data, RES))
    params = PlannerParams(algorithm="dijkstra", smooth=False, allow_unknown=allow_unknown)
    passable = cm.traversable(allow_unknown=allow_unknown)
    free = np.argwhere(cm.cost == 0)
    outcomes = set()
    for _ in range(14):
        s, g = (tuple(int(v) for v in free[rng.integers(len(free))]) for _ in range(2))
        path = GlobalPlanner(cm, params).plan(centre(cm, *s), centre(cm, *g))
        estimate = coarse_cost(cm.cost, passable, s, g, resolution_m=RES, params=params)
        outcomes.add(path is None)
        assert (estimate is None) == (path is None), (s, g, estimate, path is None)
        if path is not None and estimate is not None:
            assert abs(estimate - path.cost) <= 0.2 * path.cost + 8 * RES, (estimate, path.cost)
    assert outcomes == {True, False}, "both a path and none among the pairs"
    walled = corridor(make_map, blocked=True)
    assert coarse_cost(walled.cost, walled.traversable(), walled.cells(0.5, 1.5)[:2],  # type: ignore[arg-type]
                       walled.cells(5.5, 1.5)[:2], resolution_m=RES, params=PlannerParams()) is None


@pytest.mark.parametrize("reduced", [False, True])
def test_the_compiled_weights_are_the_numpy_weights_bit_for_bit(make_map, reduced: bool,
                                                                   numpy_baselines: ModuleType) -> None:
    """`benchmarks/numpy_baselines.py`'s numpy edge weights and the compiled ones: the same bits on a costmap with
    walls, inflation, unknown cells and corners, whole and as a patch (a window of views, as a scan's patch is), so
    every plan and every seeded run stays what it was."""
    from atemr.skills.nav.global_planner import _potential, edge_weights

    rng = np.random.default_rng(11)
    data = np.where(rng.random((90, 70)) < 0.04, 100, 0).astype(np.int8)
    data[30:60, 20:25] = -1  # unknown
    data[:, 40] = 100
    data[45:48, 40] = 0  # a doorway
    cm = Costmap(make_map(data, RES))
    params = PlannerParams()
    for passable in (cm.traversable(), cm.traversable(allow_unknown=True)):
        h = _potential(cm.shape, (80, 10), RES, params) if reduced else None
        want = numpy_baselines.numpy_edge_weights(cm.cost, passable, RES, params, h)
        assert edge_weights(cm.cost, passable, RES, params, h).tobytes() == want.tobytes()
        window = (slice(20, 70), slice(15, 55))
        want = numpy_baselines.numpy_edge_weights(cm.cost[window], passable[window], RES, params,
                                            None if h is None else h[window])
        got = edge_weights(cm.cost[window], passable[window], RES, params, None if h is None else h[window])
        assert got.tobytes() == want.tobytes()
