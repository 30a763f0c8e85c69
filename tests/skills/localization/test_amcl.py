"""AMCL: the pieces (motion model, resampling, KLD bound) and convergence in the studio with simulator scans."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from atemr.errors import ConfigError, NavigationError
from atemr.msgs import Pose2D
from atemr.skills.localization.amcl import Amcl, AmclParams, kld_bound, low_variance_resample, weighted_mean_cov
from atemr.skills.localization.geometry import as_array, compose, relative
from atemr.skills.localization.motion_model import OdometryNoise, sample_motion_model_odometry
from atemr.skills.localization.scan import scan_points


def run(amcl: Amcl, rec, start: int = 0) -> list[tuple[int, float, float, int]]:  # type: ignore[no-untyped-def]
    """Feed the recording; (scan index, position error, std, particles) after every filter update."""
    out = []
    for i in range(start, len(rec.scans)):
        if amcl.update(rec.scans[i].t, rec.odom[i], scan_points(rec.scans[i])):
            e = amcl.estimate
            out.append((i, e.pose.distance_to(rec.truth[i]), e.std_xy_m, amcl.particles.shape[0]))
    return out


def test_motion_model_without_noise_applies_odometry_exactly() -> None:
    particles = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 1.0], [-1.0, 0.5, -2.5]])
    before, after = Pose2D(3.0, 1.0, 0.4), Pose2D(3.5, 1.3, 0.9)
    moved = sample_motion_model_odometry(particles, before, after, OdometryNoise(0, 0, 0, 0),
                                         np.random.default_rng(0))
    step = relative(as_array(before), as_array(after))
    assert moved == pytest.approx(compose(particles, step))


def test_motion_model_noise_grows_with_motion() -> None:
    rng = np.random.default_rng(0)
    particles = np.zeros((20_000, 3))
    short = sample_motion_model_odometry(particles, Pose2D(), Pose2D(0.1, 0.0, 0.0), OdometryNoise(), rng)
    long = sample_motion_model_odometry(particles, Pose2D(), Pose2D(1.0, 0.0, 0.0), OdometryNoise(), rng)
    assert short[:, 0].mean() == pytest.approx(0.1, abs=0.005)
    assert long[:, 0].std() > 5 * short[:, 0].std()
    back = sample_motion_model_odometry(particles, Pose2D(), Pose2D(-0.5, 0.0, 0.0), OdometryNoise(), rng)
    assert back[:, 0].mean() == pytest.approx(-0.5, abs=0.01) and abs(back[:, 2]).mean() < 0.2  # no half turn


def test_low_variance_resampling() -> None:
    rng = np.random.default_rng(0)
    assert set(low_variance_resample(np.array([0.0, 1.0, 0.0]), 50, rng)) == {1}
    idx = low_variance_resample(np.array([0.25, 0.25, 0.5]), 400, rng)
    assert np.bincount(idx).tolist() == [100, 100, 200]  # systematic: exact proportions


def test_kld_bound_matches_chi_square_quantile() -> None:
    ks = np.array([2, 5, 20, 100, 500])
    exact = stats.chi2.ppf(0.99, ks - 1) / (2 * 0.05)
    assert kld_bound(ks, 0.05, 2.326) == pytest.approx(exact, rel=0.02)
    assert kld_bound(1, 0.05, 2.326) == 0


def test_weighted_mean_wraps_yaw() -> None:
    mean, cov = weighted_mean_cov(np.array([[0.0, 0.0, math.pi - 0.1], [0.0, 0.0, -math.pi + 0.1]]), np.ones(2))
    assert abs(abs(mean[2]) - math.pi) < 1e-9 and cov[2, 2] == pytest.approx(0.01)


def test_converges_from_known_pose(studio_map, living_room_drive) -> None:  # type: ignore[no-untyped-def]
    rec = living_room_drive
    amcl = Amcl(studio_map, np.random.default_rng(1))
    amcl.initialize(Pose2D(rec.truth[0].x_m + 0.2, rec.truth[0].y_m - 0.15, 0.15))  # a rough click
    out = run(amcl, rec)
    assert len(out) > 50
    errs = np.array([e for _, e, _, _ in out[3:]])
    assert errs.max() < 0.1 and np.sqrt(np.mean(errs**2)) < 0.05
    assert out[-1][2] < 0.1  # confident
    assert out[-1][3] < 1000  # KLD shrank the set from 5000


def test_converges_from_unknown_pose(studio_map, living_room_drive) -> None:  # type: ignore[no-untyped-def]
    rec = living_room_drive
    amcl = Amcl(studio_map, np.random.default_rng(2))
    amcl.initialize_global()
    assert amcl.estimate.std_xy_m > 1.0  # spread over the flat
    out = run(amcl, rec)
    converged_at = next(i for i, (_, e, s, _) in enumerate(out) if e < 0.1 and s < 0.1)
    assert converged_at < 25  # updates, 0.1 m or 15° of motion each
    errs = np.array([e for _, e, _, _ in out[converged_at:]])
    assert errs.max() < 0.15


def test_bad_input(studio_map) -> None:  # type: ignore[no-untyped-def]
    amcl = Amcl(studio_map, np.random.default_rng(0))
    with pytest.raises(NavigationError, match="no particles"):
        amcl.update(0.0, Pose2D(), np.zeros((0, 2)))
    with pytest.raises(NavigationError, match="finite"):
        amcl.initialize(Pose2D(float("nan"), 0.0, 0.0))
    with pytest.raises(NavigationError, match="positive definite"):
        amcl.initialize(Pose2D(2.0, 2.0, 0.0), -np.eye(3))
    amcl.initialize(Pose2D(2.6, 2.6, 0.0))
    assert not amcl.update(0.1, Pose2D(float("nan"), 0.0, 0.0), np.zeros((3, 2)))
    assert amcl.rejected == 1
    assert amcl.update(0.2, Pose2D(), np.zeros((0, 2)))  # empty scan: moved, not weighed
    assert np.isfinite(amcl.estimate.covariance).all()
    with pytest.raises(ConfigError):
        AmclParams(min_particles=10, max_particles=5)


def test_recovery_particles_find_a_kidnapped_robot(studio_map, simdrive, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """AMCL alone (no covariance monitor, no global restart): teleported 1.9 m mid-drive, the cloud fits the scans
    worse at once, w_fast falls below w_slow and uniform particles are injected until some land near the robot.
    Without them the confident cloud stays where the robot was."""
    rec = simdrive.drive(seed=4, kidnap=(8.0, Pose2D(2.45, 3.0, -math.pi / 2)), max_s=30.0)

    def final_error() -> tuple[float, float]:
        amcl = Amcl(studio_map, np.random.default_rng(0))
        amcl.initialize(rec.truth[0])
        injected = 0.0
        for i in range(len(rec.scans)):
            if amcl.update(rec.scans[i].t, rec.odom[i], scan_points(rec.scans[i])):
                injected = max(injected, amcl.random_fraction)
        return amcl.estimate.pose.distance_to(rec.truth[-1]), injected

    error, injected = final_error()
    assert injected > 0.05 and error < 0.15, (error, injected)
    monkeypatch.setattr(Amcl, "random_fraction", property(lambda self: 0.0))
    error_without, _ = final_error()
    assert error_without > 1.0, error_without
