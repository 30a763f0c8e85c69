"""Point-to-line ICP: known transforms recovered on hand-made shapes and on simulator scans."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.msgs import Pose2D
from atemr.skills.localization.geometry import as_array, as_pose, compose, inverse, relative, transform_points
from atemr.skills.localization.icp import IcpParams, IcpTarget, _median, icp
from atemr.skills.localization.scan import scan_points


def segment(a: tuple[float, float], b: tuple[float, float], spacing_m: float = 0.04) -> np.ndarray:
    n = max(2, round(math.dist(a, b) / spacing_m))
    t = np.linspace(0.0, 1.0, n)[:, None]
    return np.asarray(a) + t * (np.asarray(b) - np.asarray(a))


def room() -> np.ndarray:
    """Outline of a 4 m × 3 m room with a box in it: lines in both directions, so the motion is observable."""
    corners = [(0, 0), (4, 0), (4, 3), (0, 3), (0, 0)]
    walls = [segment(a, b) for a, b in itertools.pairwise(corners)]
    return np.concatenate([*walls, segment((1, 1), (1.6, 1)), segment((1.6, 1), (1.6, 1.4))])


@pytest.mark.parametrize("true", [(0.0, 0.0, 0.0), (0.2, -0.1, 0.15), (-0.3, 0.25, -0.2), (0.05, 0.2, 0.12)])
def test_recovers_known_transform(true: tuple[float, float, float]) -> None:
    rng = np.random.default_rng(7)
    src = room()
    tgt = transform_points(true, src) + rng.normal(0.0, 0.005, src.shape)
    r = icp(src, tgt)
    assert r.converged and r.ok
    assert np.allclose(as_array(r.pose), true, atol=0.01)
    assert r.rmse_m < 0.01
    assert r.inlier_fraction > 0.8
    assert r.iterations < 20


def test_outliers_are_rejected() -> None:
    rng = np.random.default_rng(1)
    src = room()
    true = (0.1, 0.05, 0.1)
    tgt = transform_points(true, src)
    clutter = rng.uniform(-0.5, 4.5, (60, 2))  # things in the new scan that are not in the reference
    r = icp(np.vstack([src, clutter]), tgt)
    assert r.converged
    assert np.allclose(as_array(r.pose), true, atol=0.01)
    assert r.inlier_fraction < 0.95  # the clutter was left out


def test_corridor_is_uncertain_along_its_axis() -> None:
    """Two parallel walls fix y and yaw but not x: the covariance must say so."""
    t = np.linspace(0.0, 6.0, 120)
    src = np.concatenate([np.c_[t, 0 * t - 1.0], np.c_[t, 0 * t + 1.0]])
    tgt = transform_points((0.0, 0.05, 0.02), src) + np.random.default_rng(2).normal(0, 0.005, src.shape)
    r = icp(src, tgt)
    assert abs(r.pose.y_m - 0.05) < 0.01 and abs(r.pose.yaw_rad - 0.02) < 0.01
    assert r.ok
    assert r.covariance[0, 0] > 100 * r.covariance[1, 1]  # x along the corridor: 30x the std of y


def test_too_few_points_is_not_converged_and_nan_points_are_dropped() -> None:
    r = icp(np.zeros((3, 2)), room())
    assert not r.converged and not r.ok and math.isinf(r.rmse_m)
    src = room()
    src_nan = np.vstack([src, [[np.nan, 1.0], [np.inf, 0.0]]])
    r2 = icp(src_nan, transform_points((0.1, 0.0, 0.05), src))
    assert r2.converged and abs(r2.pose.x_m - 0.1) < 0.01
    with pytest.raises(ConfigError, match="shape"):
        icp(np.zeros((5, 3)), room())
    with pytest.raises(ConfigError):
        IcpParams(max_correspondence_m=float("nan"))


def test_a_line_is_fitted_only_where_the_neighbours_are_near() -> None:
    """A map's cells: a wall, and two table legs 0.75 m apart. Without a radius the legs' ten nearest cells
    include the other leg, and a "surface" from leg to leg gets a normal; within 0.3 m only the wall does."""
    wall = np.column_stack([np.arange(0.0, 2.0, 0.05), np.zeros(40)])
    legs = np.array([[1.0, 1.0], [1.05, 1.0], [1.0, 1.05], [1.05, 1.05],
                     [1.0, 1.8], [1.05, 1.8], [1.0, 1.85], [1.05, 1.85]])
    points = np.vstack([wall, legs])
    unlimited = IcpTarget(points)
    near = IcpTarget(points, IcpParams(normal_radius_m=0.3))
    assert np.isfinite(unlimited.normals[40:, 0]).all()  # leg to leg: a line that is not there
    assert np.isnan(near.normals[40:, 0]).all()
    inner = near.normals[5:35]  # the wall away from its ends (whose nearest cells all lie on one side)
    assert np.isfinite(inner[:, 0]).all() and np.allclose(np.abs(inner[:, 1]), 1.0)
    with pytest.raises(ConfigError, match="normal_radius_m"):
        IcpParams(normal_radius_m=0.0)


def test_target_reuse_gives_same_answer() -> None:
    src = room()
    tgt = transform_points((0.1, -0.05, 0.05), src)
    prepared = IcpTarget(tgt)
    assert as_array(icp(src, prepared).pose) == pytest.approx(as_array(icp(src, tgt).pose))


def test_consecutive_simulator_scans(living_room_drive) -> None:  # type: ignore[no-untyped-def]
    """The motion between scans 0.5 s apart is recovered from the scans, starting from wheel odometry."""
    rec = living_room_drive
    errors = []
    for i in range(10, len(rec.scans) - 5, 25):
        a, b = rec.scans[i], rec.scans[i + 5]
        true = relative(as_array(rec.truth[i]), as_array(rec.truth[i + 5]))
        guess = relative(as_array(rec.odom[i]), as_array(rec.odom[i + 5]))
        r = icp(scan_points(b), scan_points(a), as_pose(guess))  # T maps b's base frame into a's
        assert r.converged
        errors.append((math.hypot(*(as_array(r.pose)[:2] - true[:2])), abs(r.pose.yaw_rad - true[2])))
    err = np.array(errors)
    assert err[:, 0].max() < 0.03 and err[:, 1].max() < 0.01


def test_a_scans_normals_come_from_its_neighbouring_beams_on_the_same_surface() -> None:
    # beam order: a wall along x at y = 2, then a jump to a post of three points a metre nearer
    wall = segment((-1.0, 2.0), (1.0, 2.0))
    post = np.array([[1.05, 1.0], [1.07, 1.0], [1.09, 1.0]])
    target = IcpTarget.from_scan(np.vstack([wall, post]))
    normals = target.normals[: len(wall)]
    assert np.allclose(np.abs(normals[:, 1]), 1.0) and np.allclose(normals[:, 0], 0.0, atol=1e-9)  # across the wall
    assert np.isnan(target.normals[len(wall):]).all()  # the post's run is too short for a line


def test_simulator_scans_match_as_well_with_beam_normals(living_room_drive) -> None:  # type: ignore[no-untyped-def]
    """What the pipeline builds (normals from neighbouring beams) recovers the motion as the k-d tree's does."""
    rec = living_room_drive
    errors = []
    for i in range(10, len(rec.scans) - 5, 25):
        true = relative(as_array(rec.truth[i]), as_array(rec.truth[i + 5]))
        guess = as_pose(relative(as_array(rec.odom[i]), as_array(rec.odom[i + 5])))
        r = icp(scan_points(rec.scans[i + 5]), IcpTarget.from_scan(scan_points(rec.scans[i])), guess)
        assert r.converged
        errors.append((math.hypot(*(as_array(r.pose)[:2] - true[:2])), abs(r.pose.yaw_rad - true[2])))
    err = np.array(errors)
    assert err[:, 0].max() < 0.03 and err[:, 1].max() < 0.01


def test_pose_algebra() -> None:
    a, b = np.array([1.0, 2.0, 0.5]), np.array([-0.3, 0.4, 2.9])
    assert np.allclose(compose(a, inverse(a)), 0.0, atol=1e-12)
    assert np.allclose(compose(a, relative(a, b)), b)
    assert as_array(Pose2D(1, 2, 3)) == pytest.approx([1, 2, 3])


def test_the_median_is_numpys() -> None:
    """ICP's `_median` (one partition) gives `np.median`'s number to the bit: odd and even sizes, ties, signed
    zeros, tiny and huge spreads, and NaN."""
    rng = np.random.default_rng(8)
    for trial in range(5000):
        n = int(rng.integers(1, 400))
        values = rng.normal(size=n) * 10.0 ** rng.uniform(-8, 8)
        if trial % 5 == 0:
            values[: n // 2] = values[0]  # ties across the middle
        if trial % 11 == 0:
            values[rng.integers(0, n, 3)] = rng.choice([0.0, -0.0])
        if trial % 97 == 0:
            values[rng.integers(0, n)] = math.nan
        want = np.float64(np.median(values))
        assert np.float64(_median(values)).tobytes() == want.tobytes(), (trial, values)
