"""AMCL: the pieces (motion model, resampling, KLD bound) and convergence in the studio with simulator scans."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError, NavigationError
from atemr.msgs import Pose2D
from atemr.skills.localization.amcl import (
    Amcl,
    AmclParams,
    heaviest_cluster,
    kld_bound,
    low_variance_resample,
    weighted_mean_cov,
)
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


def hall(side_m: float = 40.0) -> OccupancyMap:
    """An empty square hall, walled: large enough that recovery particles land tens of metres apart."""
    cells = round(side_m / 0.05)
    data = np.zeros((cells, cells), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    return OccupancyMap(data, 0.05, Pose2D(), name="hall")


def cluster_and_scatter(rng: np.random.Generator, at: tuple[float, float], n: int = 800, scattered: int = 200,
                        side_m: float = 40.0) -> np.ndarray:
    here = rng.normal([at[0], at[1], 0.3], [0.05, 0.05, 0.02], (n, 3))
    far = np.column_stack([rng.uniform(0, side_m, scattered), rng.uniform(0, side_m, scattered),
                           rng.uniform(-math.pi, math.pi, scattered)])
    return np.vstack([here, far])


def test_the_heaviest_cluster_leaves_out_particles_scattered_over_the_map() -> None:
    """Recovery particles land anywhere: the mean of the whole cloud would be metres from the robot (here 3 m)."""
    rng = np.random.default_rng(3)
    particles = cluster_and_scatter(rng, (5.0, 5.0))
    w = np.full(len(particles), 1.0 / len(particles))
    best = heaviest_cluster(particles, w, 0.25)
    assert best[:800].all() and best[800:].mean() < 0.05
    mean, _ = weighted_mean_cov(particles[best], w[best])
    whole, _ = weighted_mean_cov(particles, w)
    assert math.hypot(mean[0] - 5.0, mean[1] - 5.0) < 0.02
    assert math.hypot(whole[0] - 5.0, whole[1] - 5.0) > 2.0
    # weight decides, not the number of particles: a smaller cluster that fits the scans wins
    w2 = w.copy()
    w2[800:900] = 0.0
    particles2 = particles.copy()
    particles2[900:] = rng.normal([30.0, 30.0, 0.0], 0.05, (100, 3))
    w2[900:] = 0.01
    best2 = heaviest_cluster(particles2, w2 / w2.sum(), 0.25)
    assert best2[900:].all() and not best2[:800].any()
    # one broad cloud is one cluster, but for a few stragglers in its tails: the same mean
    broad = rng.normal([10.0, 10.0, 0.0], [1.0, 1.0, 0.3], (3000, 3))
    uniform = np.full(3000, 1 / 3000)
    kept = heaviest_cluster(broad, uniform, 0.25)
    assert kept.mean() > 0.98, kept.mean()
    assert np.allclose(weighted_mean_cov(broad[kept], uniform[kept])[0][:2], weighted_mean_cov(broad, uniform)[0][:2],
                       atol=0.05)


def test_recovery_particles_do_not_shake_the_cloud_they_join() -> None:
    """Roughening jitters the resampled particles by the spread of the cloud they came from. Recovery particles,
    scattered over a 40 m hall, are not part of that spread: counted in, they shook every particle by about half
    a metre at each resampling, and AMCL lost the robot in a warehouse."""
    amcl = Amcl(hall(), np.random.default_rng(0))
    amcl.initialize(Pose2D(20.0, 20.0, 0.3), np.diag([0.02**2, 0.02**2, 0.01**2]))
    amcl.w_slow, amcl.w_fast = 1.0, 0.8  # the scans fit worse than they used to: 20 % recovery particles
    assert amcl.random_fraction == pytest.approx(0.2)
    amcl._resample(amcl.weights)
    near = np.hypot(amcl.particles[:, 0] - 20.0, amcl.particles[:, 1] - 20.0) < 1.0
    assert 0.7 < near.mean() < 0.9, near.mean()  # the recovery particles are elsewhere in the hall
    spread = np.std(amcl.particles[near, :2], axis=0)
    assert spread.max() < 0.03, spread
