"""Ray casting against hand-made grids with known distances, a brute-force reference, the numpy traversal the
compiled walk replaced (the same bits), and circles."""

import math
from types import ModuleType

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.io.sim.raycast import GridCaster, cast_circles, cast_grid

RES = 0.1


def room(rows: int = 40, cols: int = 60) -> np.ndarray:
    """A 6 m x 4 m room at 10 cm with one-cell walls: inner faces at x=0.1, x=5.9, y=0.1, y=3.9."""
    g = np.zeros((rows, cols), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    return g


def test_axis_beams_in_a_room_hit_the_inner_faces():
    angles = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2])
    hits = cast_grid(room(), RES, (2.0, 1.5), angles, 10.0)
    np.testing.assert_allclose(hits.distance_m, [3.9, 2.4, 1.9, 1.4], atol=1e-9)
    assert hits.side.tolist() == [0, 1, 0, 1]
    assert hits.col.tolist() == [59, 20, 0, 20]
    assert hits.row.tolist() == [15, 39, 15, 0]


def test_diagonal_beam_distance_is_exact():
    # 45° from (1.0, 1.0): meets the top face y=3.9 at x=3.9, before the right face at x=5.9
    hits = cast_grid(room(), RES, (1.0, 1.0), np.array([math.pi / 4]), 10.0)
    assert hits.distance_m[0] == pytest.approx(2.9 * math.sqrt(2), abs=1e-9)


def test_single_block_and_range_limit():
    g = np.zeros((50, 50), dtype=bool)
    g[25, 40] = True  # cell covering x in [4.0, 4.1), y in [2.5, 2.6)
    hits = cast_grid(g, RES, (1.0, 2.55), np.array([0.0, math.pi]), 10.0)
    assert hits.distance_m[0] == pytest.approx(3.0)
    assert hits.distance_m[1] == math.inf  # nothing behind, the grid just ends
    short = cast_grid(g, RES, (1.0, 2.55), np.array([0.0]), 2.5)
    assert short.distance_m[0] == math.inf
    assert short.row[0] == -1 and short.side[0] == -1


def test_ray_starting_in_a_wall_has_zero_distance():
    hits = cast_grid(room(), RES, (0.05, 1.0), np.array([0.0, 1.0]), 10.0)
    assert hits.distance_m.tolist() == [0.0, 0.0]


def test_origin_outside_the_grid():
    g = room()
    hits = cast_grid(g, RES, (-1.0, 2.0), np.array([0.0, math.pi]), 10.0)
    assert hits.distance_m[0] == pytest.approx(1.0)
    assert hits.distance_m[1] == math.inf


def reference(grid: np.ndarray, res: float, origin: tuple[float, float], angle: float, max_range: float) -> float:
    """Brute force: march in steps of 1/2000 cell and report the first sample inside a blocked cell."""
    step = res / 2000
    t = np.arange(0.0, max_range, step)
    x = origin[0] + t * math.cos(angle)
    y = origin[1] + t * math.sin(angle)
    r = np.floor(y / res).astype(int)
    c = np.floor(x / res).astype(int)
    ok = (r >= 0) & (r < grid.shape[0]) & (c >= 0) & (c < grid.shape[1])
    blocked = np.zeros(t.shape, dtype=bool)
    blocked[ok] = grid[r[ok], c[ok]]
    idx = np.nonzero(blocked)[0]
    return float(t[idx[0]]) if idx.size else math.inf


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    ox=st.floats(0.0, 3.0), oy=st.floats(0.0, 2.0),
    density=st.floats(0.02, 0.3),
)
def test_matches_brute_force_on_random_grids(seed, ox, oy, density):
    rng = np.random.default_rng(seed)
    grid = rng.random((20, 30)) < density
    grid[int(oy / RES) if oy < 2.0 else 19, int(ox / RES) if ox < 3.0 else 29] = False
    angles = rng.uniform(-math.pi, math.pi, 12)
    hits = cast_grid(grid, RES, (ox, oy), angles, 2.5)
    for angle, got in zip(angles, hits.distance_m, strict=True):
        want = reference(grid, RES, (ox, oy), angle, 2.5)
        if math.isinf(want):
            assert math.isinf(got) or got > 2.5 - RES / 1000
        else:
            assert got == pytest.approx(want, abs=RES / 1000)


def test_many_chunks_long_corridor():
    # a 0.5 m wide, 60 m long corridor: rays travel far and nearly parallel to the walls
    g = np.zeros((7, 601), dtype=bool)
    g[0, :] = g[-1, :] = True
    g[:, -1] = True
    angles = np.array([0.0, 0.003, -0.003])
    hits = cast_grid(g, RES, (0.05, 0.35), angles, 100.0)
    assert hits.distance_m[0] == pytest.approx(59.95)
    for angle, d in zip(angles[1:], hits.distance_m[1:], strict=True):
        assert d == pytest.approx(reference(g, RES, (0.05, 0.35), angle, 100.0), abs=RES / 1000)


def test_circles():
    centres = np.array([[3.0, 0.0], [1.5, 1.0]])
    radii = np.array([0.5, 0.2])
    d, which = cast_circles((0.0, 0.0), np.array([0.0, math.atan2(1.0, 1.5), math.pi]), centres, radii, 10.0)
    assert d[0] == pytest.approx(2.5) and which[0] == 0
    assert d[1] == pytest.approx(math.hypot(1.5, 1.0) - 0.2) and which[1] == 1
    assert math.isinf(d[2]) and which[2] == -1
    inside, _ = cast_circles((3.0, 0.1), np.array([1.0]), centres, radii)
    assert inside[0] == 0.0
    none, idx = cast_circles((0.0, 0.0), np.array([0.0]), np.zeros((0, 2)), np.zeros(0))
    assert math.isinf(none[0]) and idx[0] == -1


def assert_same_bits(before: type, grid: np.ndarray, res: float, origin: tuple[float, float], angles: np.ndarray,
                     max_range_m) -> None:
    """``before``: `benchmarks/numpy_baselines.py`'s `NumpyGridCaster`, the traversal before the compiled walk."""
    old = before(grid, res).cast(origin, angles, max_range_m)
    new = GridCaster(grid, res).cast(origin, angles, max_range_m)
    # Bits, not closeness: every seeded scan and image stays what it was before the walk was compiled.
    assert new.distance_m.tobytes() == old.distance_m.tobytes()
    np.testing.assert_array_equal(new.row, old.row)
    np.testing.assert_array_equal(new.col, old.col)
    np.testing.assert_array_equal(new.side, old.side)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_circles=st.integers(1, 12))
def test_the_compiled_circles_answer_with_the_numpy_versions_bits(seed, n_circles, numpy_baselines: ModuleType):
    """People and pets as circles: the same distances, to the bit, and the same circles as the numpy version
    (`benchmarks/numpy_baselines.py`), from outside and inside them, with touching and equal circles (ties go to
    the first), ranges that cut them, and NaN."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-3, 3, (n_circles, 2))
    radii = rng.uniform(0.05, 0.6, n_circles)
    if n_circles > 1:
        centres[1], radii[1] = centres[0], radii[0]  # the same circle twice: the first is the one named
    origin = (float(rng.uniform(-4, 4)), float(rng.uniform(-4, 4)))
    if seed % 3 == 0:
        origin = (float(centres[-1, 0]), float(centres[-1, 1]) + 0.5 * float(radii[-1]))  # inside a circle
    aims = np.arctan2(centres[:, 1] - origin[1], centres[:, 0] - origin[0])
    angles = np.concatenate([rng.uniform(-math.pi, math.pi, 100), aims, [math.nan]])
    for reach in (math.inf, float(rng.uniform(0.5, 5.0)), math.nan):
        got = cast_circles(origin, angles, centres, radii, reach)
        want = numpy_baselines.numpy_cast_circles(origin, angles, centres, radii, reach)
        assert got[0].tobytes() == want[0].tobytes()
        np.testing.assert_array_equal(got[1], want[1])


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    where=st.sampled_from(["inside", "cell centre", "outside"]),
    per_ray_range=st.booleans(),
)
def test_the_compiled_walk_answers_with_the_numpy_traversals_bits(seed, where, per_ray_range,
                                                                  numpy_baselines: ModuleType):
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(3, 50, 2)
    grid = rng.random((rows, cols)) < rng.uniform(0.0, 0.4)
    res = float(rng.choice([0.05, 0.1]))
    if where == "outside":
        ox, oy = rng.uniform(-0.6, cols * res + 0.6), float(rng.choice([-0.3, rows * res + 0.3]))
    else:
        ox, oy = rng.uniform(0, cols * res), rng.uniform(0, rows * res)
        if where == "cell centre":  # rays through grid corners exactly: the nudge decides the cell
            ox, oy = (math.floor(ox / res) + 0.5) * res, (math.floor(oy / res) + 0.5) * res
    axes = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, -3 * math.pi / 4])
    angles = np.concatenate([rng.uniform(-math.pi, math.pi, 40), axes])
    max_range = rng.uniform(0.2, 8.0, angles.size) if per_ray_range else float(rng.uniform(0.2, 8.0))
    assert_same_bits(numpy_baselines.NumpyGridCaster, grid, res, (ox, oy), angles, max_range)


def test_the_compiled_walk_answers_with_the_numpy_traversals_bits_in_the_studio(numpy_baselines: ModuleType):
    from atemr.io.sim.simulation import build_simulation

    scene = build_simulation("studio", 3).scene
    rng = np.random.default_rng(3)
    free = np.argwhere(~scene.blocked)
    angles = -math.pi + 2 * math.pi / 360 * np.arange(360)
    for r, c in free[rng.choice(len(free), 12, replace=False)]:
        origin = ((c + rng.random()) * scene.resolution_m, (r + rng.random()) * scene.resolution_m)
        for grid in (scene.blocked, scene.walls, scene.furniture):
            assert_same_bits(numpy_baselines.NumpyGridCaster, grid, scene.resolution_m, origin,
                             angles + rng.uniform(-1, 1), 12.0)


def test_a_ray_through_a_grid_corner_names_the_vertical_face(numpy_baselines: ModuleType) -> None:
    """Crossing a grid line of each family at the same distance into a blocked cell, the walk says the ray entered
    through the vertical line (side 0). The distance and the cell are the numpy traversal's; the face it named
    depended on its chunks of crossings (here it said 1), which is the one documented difference."""
    grid = np.zeros((80, 80), dtype=bool)
    grid[16, 27] = True
    angle = np.array([math.atan2(1.0, 2.0)])
    ours = cast_grid(grid, 1.0, (5.5, 5.25), angle, 200.0)
    before = numpy_baselines.NumpyGridCaster(grid, 1.0).cast((5.5, 5.25), angle, 200.0)
    assert ours.distance_m.tobytes() == before.distance_m.tobytes()
    assert (ours.row[0], ours.col[0]) == (before.row[0], before.col[0]) == (16, 27)
    assert ours.side[0] == 0


def test_nan_angles_and_ranges_hit_nothing_and_a_ray_from_outside_ends() -> None:
    """A NaN heading or range is no hit (the numpy traversal walked such a ray forever, as would the compiled one,
    which no signal can interrupt); a ray from outside the grid with no range limit stops once past the grid."""
    hits = cast_grid(room(), RES, (2.0, 1.5), np.array([math.nan, 0.0]), 10.0)
    assert math.isinf(hits.distance_m[0]) and hits.side[0] == -1 and hits.row[0] == -1
    assert hits.distance_m[1] == pytest.approx(3.9)
    assert math.isinf(cast_grid(room(), RES, (2.0, 1.5), np.array([0.0]), math.nan).distance_m[0])
    outside = cast_grid(room(), RES, (-1.0, 2.0), np.array([0.0, math.pi, 0.3]), math.inf)
    assert outside.distance_m[0] == pytest.approx(1.0)  # into the wall at x = 0
    assert math.isinf(outside.distance_m[1])  # away from the grid
    assert outside.distance_m[2] == pytest.approx(reference(room(), RES, (-1.0, 2.0), 0.3, 10.0), abs=RES / 1000)
