"""Likelihood field and scan-to-map matching on hand-made grids and the studio map."""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
import pytest

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.geometry import as_array
from atemr.skills.localization.likelihood_field import FieldParams, LikelihoodField
from atemr.skills.localization.scan import scan_points
from atemr.skills.localization.scan_to_map import ScanToMapMatcher


def single_cell_map() -> OccupancyMap:
    data = np.zeros((20, 30), dtype=np.int8)
    data[10, 15] = 100  # cell centre at (15.5, 10.5) * 0.1 + origin
    return OccupancyMap(data, 0.1, Pose2D(-1.0, -1.0, 0.0))


def test_distance_table_is_euclidean() -> None:
    f = LikelihoodField(single_cell_map(), FieldParams(max_dist_m=1.0))
    cx, cy = -1.0 + 1.55, -1.0 + 1.05
    d = f.distance(np.array([cx, cx + 0.3, cx + 0.3, cx + 5.0, 100.0]), np.array([cy, cy, cy + 0.4, cy, 0.0]))
    assert d == pytest.approx([0.0, 0.3, 0.5, 1.0, 1.0])  # clipped at max_dist, off-map = max_dist


def test_log_likelihood_prefers_true_pose_and_counts_agreement() -> None:
    f = LikelihoodField(single_cell_map())
    point = np.array([[1.0, 0.0]])  # one metre ahead of the robot
    poses = np.array([[-0.45, 0.05, 0.0], [-0.45, 0.35, 0.0], [0.55, 1.05, -math.pi / 2]])
    ll = f.log_likelihood(poses, point)
    assert ll[0] > ll[1] and ll[2] == pytest.approx(ll[0])
    assert f.agreement(poses, point) == pytest.approx([1.0, 0.0, 1.0])
    assert f.log_likelihood(poses, np.zeros((0, 2))) == pytest.approx([0, 0, 0])


def test_rotated_origin_is_honoured() -> None:
    data = np.zeros((20, 30), dtype=np.int8)
    data[10, 15] = 100
    m = OccupancyMap(data, 0.1, Pose2D(0.0, 0.0, math.pi / 2))
    x, y = m.cell_to_world(10, 15)
    f = LikelihoodField(m)
    assert f.agreement(np.array([[float(x) - 1.0, float(y), 0.0]]), np.array([[1.0, 0.0]]))[0] == 1.0


def test_map_without_obstacles_is_refused() -> None:
    with pytest.raises(ConfigError, match="no occupied cell"):
        LikelihoodField(OccupancyMap(np.zeros((5, 5), dtype=np.int8), 0.1))
    with pytest.raises(ConfigError):
        FieldParams(sigma_hit_m=0.0)


def test_scan_points_drop_invalid_returns() -> None:
    ranges = np.array([1.0, np.nan, 0.0, np.inf, -np.inf, 0.1, 9.0, 2.0])
    scan = LaserScan(0.0, ranges, 0.0, math.pi / 4, 0.15, 8.0, Pose2D(0.1, 0.0, 0.0))
    pts = scan_points(scan)
    assert pts == pytest.approx(np.array([[1.1, 0.0], [0.1 + 2.0 * math.cos(7 * math.pi / 4),
                                                       2.0 * math.sin(7 * math.pi / 4)]]))
    assert scan_points(scan, max_beams=1).shape == (1, 2)


@pytest.mark.parametrize("offset", [(0.3, -0.2, 0.25), (-0.35, 0.3, -0.4), (0.0, 0.0, 0.0)])
def test_scan_to_map_recovers_pose(studio_map, living_room_drive, offset) -> None:  # type: ignore[no-untyped-def]
    matcher = ScanToMapMatcher(LikelihoodField(studio_map))
    rec = living_room_drive
    for i in (5, 120, 200):
        truth = as_array(rec.truth[i])
        guess = truth + np.array(offset)
        m = matcher.match(scan_points(rec.scans[i]), Pose2D(*guess), window_xy_m=0.5, window_yaw_rad=0.5)
        assert math.hypot(m.pose.x_m - truth[0], m.pose.y_m - truth[1]) < 0.05
        assert abs(m.pose.yaw_rad - truth[2]) < 0.03
        assert m.agreement > 0.8


def test_scan_to_map_bad_input(studio_map) -> None:  # type: ignore[no-untyped-def]
    matcher = ScanToMapMatcher(LikelihoodField(studio_map))
    with pytest.raises(ConfigError, match="finite"):
        matcher.match(np.zeros((5, 2)), Pose2D(float("nan"), 0.0, 0.0))
    empty = matcher.match(np.zeros((0, 2)), Pose2D(2.0, 2.0, 0.0))
    assert empty.agreement == 0.0 and empty.pose == Pose2D(2.0, 2.0, 0.0)


def test_the_compiled_cells_are_the_numpy_cells_and_the_scores_the_same_bits(numpy_baselines: ModuleType) -> None:
    """Every point's cell under every pose, from the compiled loop and from `benchmarks/numpy_baselines.py`'s numpy
    ``_indices``: the same, on and off a rotated map, for NaN, infinite and absurd poses and points; so AMCL's
    weights, the matchers' scores and every distance are the same bits, and every seeded run what it was."""
    rng = np.random.default_rng(3)
    data = np.where(rng.random((60, 80)) < 0.05, 100, 0).astype(np.int8)
    for origin in (Pose2D(-1.5, 2.0, 0.0), Pose2D(0.3, -0.7, 0.6)):
        grid = OccupancyMap(data, 0.05, origin)
        ours, before = LikelihoodField(grid), numpy_baselines.NumpyLikelihoodField(grid)
        # A million cells, most on the map: enough that float32 rounding in another order would move some.
        poses = np.column_stack([origin.x_m + rng.uniform(0, 4, 3000), origin.y_m + rng.uniform(0, 3, 3000),
                                 rng.uniform(-4, 4, 3000)])
        poses[:4] = [(1e12, 0.0, 0.0), (np.nan, 1.0, 0.2), (0.5, 0.5, np.inf), (np.inf, -np.inf, 0.0)]
        points = rng.uniform(-2, 2, (360, 2))
        points[:2] = [(np.nan, 0.0), (np.inf, -np.inf)]
        np.testing.assert_array_equal(ours._indices(poses, points), before._indices(poses, points))
        assert ours.log_likelihood(poses, points).tobytes() == before.log_likelihood(poses, points).tobytes()


def test_a_segment_too_long_for_its_steps_to_move_ends_the_walk() -> None:
    """Sphere tracing adds steps of at least half a cell; past 1e300 m a step no longer moves a float, so such a
    segment ends where floats end instead of walking for ever (uninterruptibly, in a compiled loop)."""
    data = np.zeros((40, 40), dtype=np.int8)
    data[20, 20] = 100
    field = LikelihoodField(OccupancyMap(data, 0.05, Pose2D(0.0, 0.0, 0.0)))
    poses = np.zeros((3000, 3))
    crossed = field.crossings(poses, (0.0, 0.0), np.array([[1e300, 0.0], [2.0, 1.0]]), 0.0)
    assert crossed.shape == (3000, 2) and not crossed.any()
