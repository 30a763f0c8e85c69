"""Adaptive Monte Carlo localization (AMCL) against an occupancy map, vectorised over particles × beams.

The algorithm is that of ROS amcl and Probabilistic Robotics (ch. 8):

* **motion**: every particle is moved by the odometry motion since the last filter update, with noise
  (`sample_motion_model_odometry`, alpha1..4). The filter updates only after the robot has moved
  ``update_min_d_m`` or turned ``update_min_a_rad`` (a standing robot would otherwise resample its cloud
  into one point on a single scan's noise);
* **measurement**: the likelihood field (`LikelihoodField`, precomputed with a distance transform)
  scores ``max_beams`` valid beams for all particles at once; log weights are normalised with
  log-sum-exp. Beams are not independent (neighbours see the same wall), so the summed log-likelihood
  is multiplied by ``beam_weight`` < 1, which keeps the posterior from being overconfident;
* **recovery particles** (augmented MCL, table 8.3): short- and long-term averages ``w_fast``/``w_slow``
  of the measurement likelihood; when the short-term one falls below the long-term one (the scans
  suddenly fit worse: kidnapping, a wrong convergence), a fraction ``1 − w_fast/w_slow`` of the new
  particles is drawn uniformly over free space. The likelihood averaged is the per-beam geometric mean,
  so its scale does not depend on how many beams are used;
* **resampling**: when the effective sample size falls below ``resample_neff`` of the particles (or
  recovery particles are due), low-variance (systematic) resampling, with the particle count chosen by KLD sampling
  (Fox 2003): particles are drawn in random order until their number exceeds the bound for the number
  ``k`` of histogram bins they occupy, ``n = (k−1)/(2ε) · (1 − 2/(9(k−1)) + √(2/(9(k−1))) z)³``, clipped to
  [min_particles, max_particles]. Done vectorised: draw ``max_particles`` once, count the distinct bins
  of every prefix, take the shortest prefix that satisfies the bound;
* **output**: the weighted mean pose (circular mean for the yaw) and 3×3 covariance of the heaviest cluster
  (as ROS amcl reports its best cluster): the particles in KLD bins (``bin_xy_m``) joined to their
  neighbours, the cluster with the most weight. Recovery particles are scattered over the whole map; in the
  mean of the whole cloud a few of them pulled the pose metres off in a large building.

Initialisation: from the operator's pose with a covariance (Gaussian cloud), or global (uniform over
the map's free cells, uniform yaw).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.special import logsumexp

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError, NavigationError
from atemr.msgs import Pose2D
from atemr.skills.diff_drive import wrap_angle
from atemr.skills.localization.geometry import FloatArray, is_finite_pose
from atemr.skills.localization.likelihood_field import FieldParams, LikelihoodField
from atemr.skills.localization.motion_model import OdometryNoise, sample_motion_model_odometry
from atemr.skills.localization.scan import evenly_spread


@dataclass(frozen=True)
class AmclParams:
    """AMCL's parameters; names follow ROS amcl where there is one."""

    min_particles: int = 300
    max_particles: int = 5000
    #: Particles of a global initialisation (only until the first resampling, which caps at max_particles):
    #: spread over a whole flat, more hypotheses put one close enough to the truth to win at once.
    global_particles: int = 20_000
    #: KLD bound: maximum error ε between the sample and true posterior, and the upper (1−δ) normal quantile.
    kld_err: float = 0.05
    kld_z: float = 2.326
    #: Histogram bins for KLD (x, y in metres; yaw in radians).
    bin_xy_m: float = 0.25
    bin_yaw_rad: float = math.radians(10.0)
    max_beams: int = 60
    update_min_d_m: float = 0.1
    update_min_a_rad: float = math.radians(15.0)
    #: Exponent on the summed beam likelihood, for correlated beams (1: independent beams).
    beam_weight: float = 0.15
    #: Resample only when the effective sample size ``1/Σw²`` falls below this fraction of the particles
    #: (selective resampling, Grisetti 2007): weights then accumulate over several scans instead of the
    #: cloud being copied onto itself after each, which keeps its diversity (1.0: resample every update).
    resample_neff: float = 0.5
    #: Roughening after resampling (Gordon 1993): jitter of std ``K · spread · n^(-1/3)`` per dimension, so a
    #: cloud that collapsed onto the nearest of too few hypotheses can still slide onto the true pose.
    roughening: float = 0.2
    recovery_alpha_slow: float = 0.001
    recovery_alpha_fast: float = 0.1
    noise: OdometryNoise = field(default_factory=OdometryNoise)
    field: FieldParams = field(default_factory=FieldParams)

    def __post_init__(self) -> None:
        if not 1 <= self.min_particles <= self.max_particles:
            raise ConfigError(f"need 1 <= min_particles <= max_particles, got {self.min_particles}, "
                              f"{self.max_particles}", path="localization.min_particles")
        if self.max_beams < 1:
            raise ConfigError(f"must be >= 1, got {self.max_beams}", path="localization.max_beams")
        for name in ("kld_err", "kld_z", "bin_xy_m", "bin_yaw_rad", "beam_weight"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.{name}")
        if not 0.0 < self.resample_neff <= 1.0:
            raise ConfigError(f"must be within (0, 1], got {self.resample_neff!r}", path="localization.resample_neff")
        for name in ("update_min_d_m", "update_min_a_rad", "roughening"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"must be a finite number >= 0, got {value!r}", path=f"localization.{name}")
        if not 0 <= self.recovery_alpha_slow < self.recovery_alpha_fast <= 1:
            raise ConfigError("need 0 <= recovery_alpha_slow < recovery_alpha_fast <= 1",
                              path="localization.recovery_alpha_slow")


@dataclass(frozen=True)
class PoseEstimate:
    """A pose with its 3×3 covariance (x, y, yaw) and the time it refers to."""

    t: float
    pose: Pose2D
    covariance: FloatArray

    @property
    def std_xy_m(self) -> float:
        """Largest standard deviation of the position (square root of the larger eigenvalue)."""
        return float(math.sqrt(max(0.0, float(np.linalg.eigvalsh(self.covariance[:2, :2])[-1]))))

    @property
    def std_yaw_rad(self) -> float:
        return float(math.sqrt(max(0.0, float(self.covariance[2, 2]))))


def low_variance_resample(weights: FloatArray, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Indices of ``n`` draws by systematic resampling (one random offset, evenly spaced pointers)."""
    c = np.cumsum(weights)
    c /= c[-1]
    u = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(c, u, side="left"), weights.size - 1).astype(np.intp)


def kld_bound(k: NDArray[np.int_] | int, err: float, z: float) -> FloatArray:
    """Particles needed for ``k`` occupied bins (Fox 2003, eq. 12); 0 for ``k <= 1``."""
    kk = np.asarray(k, dtype=np.float64)
    km1 = np.maximum(kk - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    n = km1 / (2.0 * err) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(kk <= 1, 0.0, n)


#: Beyond this many cells the cloud's bounding box is not clustered (a cloud spread over kilometres is one answer).
_MAX_CLUSTER_CELLS = 4_000_000


def heaviest_cluster(particles: FloatArray, weights: FloatArray, cell_m: float) -> NDArray[np.bool_]:
    """Which particles belong to the heaviest cluster: cells of ``cell_m`` holding particles, joined to their eight
    neighbours, the one whose particles carry the most weight (all of them when there is one cluster)."""
    ix = np.floor(particles[:, 0] / cell_m).astype(np.int64)
    iy = np.floor(particles[:, 1] / cell_m).astype(np.int64)
    ix -= ix.min()
    iy -= iy.min()
    shape = (int(iy.max()) + 1, int(ix.max()) + 1)
    everything = np.ones(particles.shape[0], dtype=bool)
    if shape[0] * shape[1] > _MAX_CLUSTER_CELLS:
        return everything
    occupied = np.zeros(shape, dtype=bool)
    occupied[iy, ix] = True
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3), dtype=bool))
    if count <= 1:
        return everything
    label = labels[iy, ix]
    totals = np.bincount(label, weights=weights, minlength=count + 1)
    return np.asarray(label == int(np.argmax(totals)), dtype=bool)


def weighted_mean_cov(particles: FloatArray, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Weighted mean (circular for yaw) and covariance of a particle set."""
    w = weights / weights.sum()
    mx, my = float(w @ particles[:, 0]), float(w @ particles[:, 1])
    myaw = math.atan2(float(w @ np.sin(particles[:, 2])), float(w @ np.cos(particles[:, 2])))
    d = np.column_stack([particles[:, 0] - mx, particles[:, 1] - my, wrap_angle(particles[:, 2] - myaw)])
    cov = (d * w[:, None]).T @ d
    return np.array([mx, my, myaw]), cov


class Amcl:
    """The particle filter's state between updates. ``rng`` is owned by the caller (seeded runs repeat)."""

    def __init__(
        self,
        grid: OccupancyMap,
        rng: np.random.Generator,
        params: AmclParams | None = None,
        likelihood: LikelihoodField | None = None,
    ) -> None:
        self.params = p = params or AmclParams()
        self.map = grid
        self.rng = rng
        self.field = likelihood or LikelihoodField(grid, p.field)
        rows, cols = np.nonzero(grid.free)
        if rows.size == 0:
            raise ConfigError(f"map '{grid.name}' has no free cell: nowhere to localize")
        self._free_rows, self._free_cols = rows, cols
        self.particles: FloatArray = np.zeros((0, 3))
        self.weights: FloatArray = np.zeros(0)
        self.w_slow = 0.0
        self.w_fast = 0.0
        self.updates = 0
        self.rejected = 0
        self._odom_ref: Pose2D | None = None
        self._force = False
        self._estimate: PoseEstimate | None = None
        self._last_t = 0.0

    # -- initialisation --------------------------------------------------------------------------
    @property
    def initialized(self) -> bool:
        return self.particles.shape[0] > 0

    def initialize(self, pose: Pose2D, covariance: FloatArray | None = None, *, now: float = 0.0,
                   odom: Pose2D | None = None) -> None:
        """Start from the operator's pose: a Gaussian cloud of ``max_particles`` (default σ 0.25 m, 0.25 rad).

        ``odom``: the odometry pose ``pose`` refers to (the next update moves the cloud by the odometry since
        then; without it, since the last update). Raises `NavigationError` for a non-finite pose or an invalid
        covariance (the dashboard shows it).
        """
        if not is_finite_pose(pose):
            raise NavigationError(f"initial pose must be finite, got {pose}")
        cov = np.diag([0.25**2, 0.25**2, 0.25**2]) if covariance is None else np.asarray(covariance, np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise NavigationError(f"initial covariance must be a finite 3x3 matrix, got shape {cov.shape}")
        try:
            chol = np.linalg.cholesky(0.5 * (cov + cov.T) + 1e-12 * np.eye(3))
        except np.linalg.LinAlgError:
            raise NavigationError("initial covariance must be positive definite") from None
        n = self.params.max_particles
        mean = np.array([pose.x_m, pose.y_m, pose.yaw_rad])
        self.particles = mean + self.rng.standard_normal((n, 3)) @ chol.T
        self.particles[:, 2] = wrap_angle(self.particles[:, 2])
        if odom is not None and is_finite_pose(odom):
            self._odom_ref = odom
        self._reset(now)

    def initialize_global(self, *, now: float = 0.0) -> None:
        """Global localization: ``global_particles`` spread uniformly over free space, uniform yaw."""
        self.particles = self._uniform_free(max(self.params.global_particles, self.params.max_particles))
        self._reset(now)

    def _reset(self, now: float) -> None:
        n = self.particles.shape[0]
        self.weights = np.full(n, 1.0 / n)
        self.w_slow = self.w_fast = 0.0
        self._force = True
        self._last_t = now
        self._estimate_from(now, self.weights)

    def request_update(self) -> None:
        """Weigh the next scan even if the robot has not moved (ROS amcl's ``request_nomotion_update``).

        For global localization of a robot that stands still (the agent stops it while it is lost).
        """
        self._force = True

    def _uniform_free(self, n: int) -> FloatArray:
        pick = self.rng.integers(0, self._free_rows.size, n)
        jitter = self.rng.random((2, n)) - 0.5
        x, y = self.map.cell_to_world(self._free_rows[pick] + jitter[0], self._free_cols[pick] + jitter[1])
        yaw = self.rng.uniform(-math.pi, math.pi, n)
        return np.column_stack([x, y, yaw])

    # -- update ----------------------------------------------------------------------------------
    def update(self, now: float, odom: Pose2D, points: FloatArray) -> bool:
        """Feed the odometry pose and the scan taken with it (base-frame points, see `scan_points`).

        Returns True when the filter ran (moved enough since the last update, or just initialised).
        A non-finite odometry pose or ``now`` is dropped (counted in ``rejected``); an empty scan moves
        the particles but does not weigh them.
        """
        if not self.initialized:
            raise NavigationError("AMCL has no particles: set an initial pose or start global localization")
        if not (math.isfinite(now) and is_finite_pose(odom)):
            self.rejected += 1
            return False
        if self._odom_ref is None:
            self._odom_ref = odom
        ref = self._odom_ref
        moved = math.hypot(odom.x_m - ref.x_m, odom.y_m - ref.y_m)
        turned = abs(float(wrap_angle(odom.yaw_rad - ref.yaw_rad)))
        p = self.params
        if not self._force and moved < p.update_min_d_m and turned < p.update_min_a_rad:
            return False
        self.particles = sample_motion_model_odometry(self.particles, ref, odom, p.noise, self.rng)
        self._odom_ref = odom
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        pts = pts[np.isfinite(pts).all(axis=1)]
        if pts.shape[0] > p.max_beams:
            pts = pts[evenly_spread(pts.shape[0], p.max_beams)]
        if pts.shape[0] == 0:
            self._estimate_from(now, self.weights)
            return True
        self._force = False
        loglik = self.field.log_likelihood(self.particles, pts)
        logw = np.log(np.maximum(self.weights, 1e-300)) + p.beam_weight * loglik
        w = np.exp(logw - logsumexp(logw))
        # Augmented MCL on the per-beam geometric-mean likelihood (scale-free in the beam count).
        quality = float(self.weights @ np.exp(loglik / pts.shape[0]))
        if self.w_slow == 0.0:
            self.w_slow = self.w_fast = quality
        else:
            self.w_slow += p.recovery_alpha_slow * (quality - self.w_slow)
            self.w_fast += p.recovery_alpha_fast * (quality - self.w_fast)
        self._estimate_from(now, w)
        if 1.0 / float(w @ w) < p.resample_neff * w.size or self.random_fraction > 0.0:
            self._resample(w)
        else:
            self.weights = w
        self.updates += 1
        return True

    def _estimate_from(self, now: float, w: FloatArray) -> None:
        best = heaviest_cluster(self.particles, w, self.params.bin_xy_m)
        mean, cov = weighted_mean_cov(self.particles[best], w[best])
        self._estimate = PoseEstimate(now, Pose2D(float(mean[0]), float(mean[1]), float(mean[2])), cov)
        self._last_t = now

    @property
    def random_fraction(self) -> float:
        """Share of recovery particles the next resampling will inject, ``max(0, 1 − w_fast/w_slow)``."""
        if self.w_slow <= 0.0:
            return 0.0
        return max(0.0, 1.0 - self.w_fast / self.w_slow)

    def _resample(self, w: FloatArray) -> None:
        p = self.params
        n_max = p.max_particles
        idx = self.rng.permutation(low_variance_resample(w, n_max, self.rng))
        new = self.particles[idx]
        frac = self.random_fraction
        inject = np.zeros(n_max, dtype=bool)  # the recovery particles
        if frac > 0.0:
            inject = self.rng.random(n_max) < frac
            count = int(inject.sum())
            if count:
                new[inject] = self._uniform_free(count)
        # KLD: shortest prefix (in this random order) whose size reaches the bound for its bin count.
        bx = np.floor(new[:, 0] / p.bin_xy_m).astype(np.int64) + (1 << 20)
        by = np.floor(new[:, 1] / p.bin_xy_m).astype(np.int64) + (1 << 20)
        bt = np.floor((new[:, 2] + math.pi) / p.bin_yaw_rad).astype(np.int64)
        keys = (bx * (1 << 21) + by) * 64 + bt
        _, first = np.unique(keys, return_index=True)
        first.sort()
        sizes = np.arange(1, n_max + 1)
        k = np.searchsorted(first, sizes, side="left")  # distinct bins among the first `size` particles
        enough = sizes >= np.maximum(kld_bound(k, p.kld_err, p.kld_z), p.min_particles)
        n = int(sizes[np.argmax(enough)]) if enough.any() else n_max
        new = new[:n]
        if p.roughening > 0.0 and n > 1:
            # The spread of the resampled cloud only: recovery particles lie anywhere on the map, and their range
            # (tens of metres in a warehouse) would shake every particle by half a metre at each resampling.
            drawn = new[~inject[:n]]
            if len(drawn) > 1:
                spread = np.ptp(drawn[:, :2], axis=0)
                yaw_spread = float(np.ptp(wrap_angle(drawn[:, 2] - drawn[0, 2])))
                sigma = p.roughening * np.array([spread[0], spread[1], yaw_spread]) * n ** (-1.0 / 3.0)
                new = new + self.rng.standard_normal(new.shape) * sigma
                new[:, 2] = wrap_angle(new[:, 2])
        self.particles = new
        self.weights = np.full(n, 1.0 / n)

    # -- output ----------------------------------------------------------------------------------
    @property
    def estimate(self) -> PoseEstimate:
        """The latest pose and covariance (as of the last filter update or initialisation)."""
        if self._estimate is None:
            raise NavigationError("AMCL has no estimate yet: set an initial pose or start global localization")
        return self._estimate

    @property
    def odom_reference(self) -> Pose2D | None:
        """The odometry pose the estimate refers to (compose the odometry since then onto it)."""
        return self._odom_ref


__all__ = ["Amcl", "AmclParams", "PoseEstimate", "heaviest_cluster", "kld_bound", "low_variance_resample",
           "weighted_mean_cov"]
