import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.io.sim.simulation import build_simulation
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.nav.costmap import (
    INSCRIBED,
    LETHAL,
    NO_INFORMATION,
    Costmap,
    CostmapParams,
    inflation_costs,
)

RES = 0.05


def one_obstacle(make_map, unknown_corner=False):
    data = np.zeros((41, 41), dtype=np.int8)
    data[20, 20] = 100
    if unknown_corner:
        data[:5, :5] = -1
    return make_map(data, RES)


def test_inflation_values_follow_the_exponential_decay(make_map):
    params = CostmapParams(robot_radius_m=0.25, footprint_padding_m=0.05, inflation_radius_m=0.6, cost_scaling=6.0)
    cm = Costmap(one_obstacle(make_map), params)
    cost = cm.cost
    assert cost[20, 20] == LETHAL
    # Cells within the inscribed radius (0.30 m = 6 cells) are INSCRIBED, including the diagonal (4, 4) cells
    # (0.283 m) and excluding (5, 4) (0.320 m).
    assert cost[20, 26] == INSCRIBED and cost[24, 24] == INSCRIBED
    assert cost[25, 24] < INSCRIBED
    # Beyond: 252 * exp(-6 (d - 0.30)), floored; d = 0.40 m (8 cells) and 0.55 m (11 cells).
    assert cost[20, 28] == math.floor(252 * math.exp(-6 * 0.10))
    assert cost[20, 31] == math.floor(252 * math.exp(-6 * 0.25))
    # Past the inflation radius (0.6 m = 12 cells): free.
    assert cost[20, 33] == 0 and cost[0, 0] == 0
    # Monotone: cost never rises with the distance.
    row = cost[20, 20:].astype(int)
    assert (np.diff(row) <= 0).all()


def test_inflation_costs_is_the_distance_rule():
    p = CostmapParams()
    d = np.array([0.0, 0.1, p.inscribed_radius_m, p.inscribed_radius_m + 0.05, p.inflation_radius_m + 0.01])
    out = inflation_costs(d, p)
    assert out.tolist() == [LETHAL, INSCRIBED, INSCRIBED, math.floor(252 * math.exp(-p.cost_scaling * 0.05)), 0]


@pytest.mark.parametrize(("policy", "corner"), [("lethal", LETHAL), ("free", 0), ("unknown", NO_INFORMATION)])
def test_unknown_space_policy(make_map, policy, corner):
    cm = Costmap(one_obstacle(make_map, unknown_corner=True), CostmapParams(unknown=policy))
    assert cm.cost[0, 0] == corner
    assert cm.traversable(allow_unknown=True)[0, 0] == (policy != "lethal")
    assert not cm.traversable()[0, 0] or policy == "free"


def test_bad_params_are_navigation_errors():
    with pytest.raises(NavigationError, match="robot_radius_m"):
        CostmapParams(robot_radius_m=float("nan"))
    with pytest.raises(NavigationError, match="unknown"):
        CostmapParams(unknown="maybe")  # type: ignore[arg-type]


def scan_of(ranges, beams=None):
    r = np.asarray(ranges, dtype=np.float64)
    n = len(r) if beams is None else beams
    return LaserScan(0.0, r, -math.pi, 2 * math.pi / n, 0.15, 8.0, Pose2D())


def test_scan_marks_returns_and_clears_along_beams(make_room, make_map):
    cm = Costmap(make_map(make_room(100, 100), RES))
    pose = Pose2D(2.5, 2.5, 0.0)
    # One beam straight ahead (+x) returning at 1.0 m: the cell at x = 3.5 is marked.
    ranges = np.full(360, np.inf)
    ahead = 180  # angle_min -pi + 180 * 1 deg = 0
    ranges[ahead] = 1.0
    assert cm.update_from_scan(scan_of(ranges), pose) == 1
    row, col, _ = cm.cells(3.5, 2.5)
    assert cm.obstacles[row, col]
    assert cm.cost[row, col] == LETHAL
    # The obstacle walks away: the same beam now returns at 2.0 m, clearing the old cell and marking the new.
    ranges[ahead] = 2.0
    cm.update_from_scan(scan_of(ranges), pose)
    assert not cm.obstacles[row, col]
    r2, c2, _ = cm.cells(4.5, 2.5)
    assert cm.obstacles[r2, c2] and cm.obstacles.sum() == 1


def test_invalid_returns_neither_mark_nor_clear(make_room, make_map):
    cm = Costmap(make_map(make_room(100, 100), RES))
    pose = Pose2D(2.5, 2.5, 0.0)
    ranges = np.full(360, np.inf)
    ranges[180] = 1.0
    cm.update_from_scan(scan_of(ranges), pose)
    before = cm.obstacles.copy()
    junk = np.full(360, np.nan)
    junk[::3] = 0.0
    junk[1::3] = np.inf
    cm.update_from_scan(scan_of(junk), pose)
    assert np.array_equal(cm.obstacles, before)
    # -inf: closer than the minimum range, an obstacle at the minimum range.
    close = np.full(360, np.inf)
    close[0] = -np.inf  # behind the robot
    cm.update_from_scan(scan_of(close), pose)
    row, col, _ = cm.cells(2.5 - 0.15, 2.5)
    assert cm.obstacles[row, col]


def test_clear_obstacles_forgets_the_layer_but_not_the_map(make_room, make_map):
    cm = Costmap(make_map(make_room(100, 100), RES))
    ranges = np.full(360, np.inf)
    ranges[180] = 1.0
    cm.update_from_scan(scan_of(ranges), Pose2D(2.5, 2.5, 0.0))
    assert cm.obstacles.any()
    cm.clear_obstacles()
    assert not cm.obstacles.any()
    assert cm.cost[0, 0] == LETHAL  # the wall stays
    assert cm.cost[50, 70] == 0


def test_non_finite_pose_is_refused(make_room, make_map):
    cm = Costmap(make_map(make_room(), RES))
    with pytest.raises(NavigationError, match="finite"):
        cm.update_from_scan(scan_of(np.ones(360)), Pose2D(float("nan"), 1.0, 0.0))


def test_studio_scan_marks_the_unmapped_basket_and_not_the_walls():
    sim = build_simulation("studio", 5)
    sim.kidnap(Pose2D(3.0, 1.2, 0.0))  # the laundry basket (not in the map) is at (3.9, 1.1), r 0.22
    scan = sim.read_lidar(0.0)
    cm = Costmap(sim.world.map)
    cm.update_from_scan(scan, sim.pose)
    rows, cols = np.nonzero(cm.obstacles)
    x, y = sim.world.map.cell_to_world(rows, cols)
    near_basket = np.hypot(x - 3.9, y - 1.1) < 0.3
    assert near_basket.sum() >= 5
    # Everything else marked is within the obstacle range and not on a mapped wall.
    assert not cm.static_lethal[rows, cols].any()
    assert (np.hypot(x - 3.0, y - 1.2) <= cm.params.obstacle_range_m + 0.2).all()
    # The basket makes the cells around it inscribed for planning.
    assert cm.cost_at(3.9 - 0.4, 1.1) >= INSCRIBED


def test_a_wall_seen_from_a_slightly_wrong_pose_is_not_marked():
    """A far wall seen with the heading a degree off lands returns a few cells beside it: that is the wall,
    not something new (marked, it would never clear: the beams that could clear it end on it)."""
    sim = build_simulation("studio", 5)
    sim.kidnap(Pose2D(2.6, 2.6, 0.0))  # living room centre: walls 2.4-2.9 m away, nothing unmapped in between
    scan = sim.read_lidar(0.0)
    cm = Costmap(sim.world.map)
    off = Pose2D(2.6, 2.6, math.radians(1.0))
    cm.update_from_scan(scan, off)
    rows, cols = np.nonzero(cm.obstacles)
    x, y = sim.world.map.cell_to_world(rows, cols)
    basket, plant = np.hypot(x - 3.9, y - 1.1) < 0.35, np.hypot(x - 4.9, y - 0.5) < 0.35
    carer = np.hypot(x - sim.movers.items[0].x_m, y - sim.movers.items[0].y_m) < 0.35
    assert not (~basket & ~plant & ~carer).any(), list(zip(x.round(2), y.round(2), strict=True))
    # Without the range allowance (a cell and a half only), the same scan marks wall cells.
    strict = Costmap(sim.world.map, CostmapParams(wall_match_m=0.0, wall_match_per_m=0.0))
    strict.update_from_scan(scan, off)
    assert strict.obstacles.sum() > cm.obstacles.sum()


def test_one_point_is_looked_up_as_in_an_array_inside_outside_and_on_edges(make_map):
    """`Costmap.cells` takes a shortcut for a single point (the robot's own cell, many times a tick): the same
    row, column and inside flag, and so the same cost, as the array path, on a rotated map, off it on every side and
    on cell edges."""
    from atemr.domain.maps import OccupancyMap

    rng = np.random.default_rng(5)
    data = rng.choice(np.array([0, 100, -1], dtype=np.int8), size=(30, 40), p=[0.8, 0.1, 0.1])
    rotated = OccupancyMap(data, RES, Pose2D(-0.7, 0.4, 0.3), name="rotated")
    for cm in (Costmap(make_map(data, RES)), Costmap(rotated)):
        xs = np.concatenate([rng.uniform(-2.0, 4.0, 300), np.arange(-0.1, 2.1, RES)])
        ys = np.concatenate([rng.uniform(-2.0, 4.0, 300), np.arange(-0.1, 2.1, RES)[::-1]])
        rows, cols, inside = cm.cells(xs, ys)
        costs = cm.cost_at(xs, ys)
        for k, (x, y) in enumerate(zip(xs.tolist(), ys.tolist(), strict=True)):
            row, col, ok = cm.cells(x, y)
            assert (int(row), int(col), bool(ok)) == (rows[k], cols[k], inside[k]), (x, y)
            assert int(cm.cost_at(x, y)) == costs[k]
        assert inside.any() and not inside.all()


def test_the_compiled_clearing_empties_the_cells_the_numpy_one_did(numpy_baselines):
    """`benchmarks/numpy_baselines.py`'s numpy clearing (every beam's samples at once) and the compiled loop empty
    the same cells, scan after scan: round the studio from poses a little off (so walls get marked, then cleared),
    and on a plain and a rotated map with random returns, dropouts and too-close beams, and from cell corners along
    the grid's lines (samples on cell edges). Every other scan starts from a layer marked everywhere, so that every
    sample's cell shows. A seeded run's obstacle layer stays what it was."""
    from atemr.domain.maps import OccupancyMap

    sim = build_simulation("studio", 6)
    rng = np.random.default_rng(6)
    data = rng.choice(np.array([0, 100, -1], dtype=np.int8), size=(60, 80), p=[0.9, 0.05, 0.05])
    grids = (OccupancyMap(data, RES, Pose2D(-0.7, 0.4, 0.3), name="rotated"), OccupancyMap(data, RES, name="plain"))
    scans = []
    while len(scans) < 40:
        x, y = float(rng.uniform(1.0, 8.0)), float(rng.uniform(0.5, 6.0))
        if sim.clearance_at(x, y).clearance_m <= 0.0:
            continue
        sim.kidnap(Pose2D(x, y, float(rng.uniform(-3, 3))))
        off = Pose2D(sim.pose.x_m + float(rng.normal(0, 0.1)), sim.pose.y_m + float(rng.normal(0, 0.1)),
                     sim.pose.yaw_rad + float(rng.normal(0, 0.05)))
        scans.append((sim.world.map, sim.read_lidar(0.0), off))
    for k in range(200):
        grid = grids[k % 2]
        ranges = rng.uniform(0.05, 5.0, 360)
        ranges[rng.random(360) < 0.1] = rng.choice([np.nan, np.inf, -np.inf, 0.0])
        pose = Pose2D(float(rng.uniform(0, 3)), float(rng.uniform(0, 3)), float(rng.uniform(-3, 3)))
        if k % 3 == 0:  # from a cell corner, along the grid's lines
            row, col = (int(v) for v in rng.integers(5, 40, 2))
            x, y = grid.cell_to_world(row - 0.5, col - 0.5)
            pose = Pose2D(float(x), float(y), grid.origin.yaw_rad + math.pi / 2 * int(rng.integers(4)))
            ranges = np.full(360, 0.05 + 0.025 * int(rng.integers(4, 80)))
        scans.append((grid, scan_of(ranges), pose))
    costmaps: dict = {}
    cleared = 0
    for k, (grid, scan, pose) in enumerate(scans):
        ours, before = costmaps.setdefault(grid.name, (Costmap(grid), numpy_baselines.NumpyClearingCostmap(grid)))
        if k % 2:
            ours.obstacles[:] = before.obstacles[:] = True
        marked = ours.obstacles.sum()
        assert ours.update_from_scan(scan, pose) == before.update_from_scan(scan, pose)
        np.testing.assert_array_equal(ours.obstacles, before.obstacles)
        np.testing.assert_array_equal(ours.unmapped_points, before.unmapped_points)
        assert ours.version == before.version
        cleared += int(ours.obstacles.sum() < marked)
    assert cleared >= 100  # clearing did happen, or the comparison proves little
