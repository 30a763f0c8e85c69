"""Point-to-line ICP (Censi 2008, PL-ICP in its linearised form) for 2-D scans.

Given source points ``P`` (the new scan) and target points ``Q`` (a reference scan or the map's
surfaces) it finds the rigid transform ``T = (x, y, θ)`` with ``T ⊕ P ≈ Q``. Point-to-line converges in
a handful of iterations where point-to-point needs dozens, because a point sliding along a wall costs
nothing: only the distance *across* the wall is penalised.

Each iteration:

1. correspondences: nearest target point of each transformed source point (`scipy.spatial.cKDTree`,
   built once per target); the target's local line normal comes from the principal axes of its
   neighbourhood (precomputed, closed form for 2×2 covariances): its ``k`` nearest neighbours for an
   unordered set (the map's surfaces), or, for a scan (`IcpTarget.from_scan`), the beams beside it on the
   same surface, which needs no search at all (window sums of running totals);
2. outlier rejection: pairs farther than ``max_correspondence_m`` are dropped, then pairs whose
   point-to-line residual exceeds ``reject_sigmas`` robust standard deviations (1.4826·MAD), and targets
   that are not on a line (isotropic neighbourhoods: corners, clutter) carry no normal and are dropped;
3. one Gauss-Newton step on ``Σ (nᵢ·(R pᵢ + t − qᵢ))²``, linearised in (δx, δy, δθ), composed onto T.

Quality: ``rmse_m`` of the inlier residuals, ``inlier_fraction`` of the source points, ``converged``
(the step fell below the tolerances), and ``covariance`` = σ²(JᵀJ)⁻¹ (Censi's Hessian estimate), which
is large along a corridor where the scan cannot fix the motion: the EKF then trusts it less there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from atemr.errors import ConfigError
from atemr.msgs import Pose2D
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, compose, transform_points

#: Coordinates beyond this are not lidar points (and would overflow squared distances): dropped.
MAX_COORD_M = 1e6


@dataclass(frozen=True)
class IcpParams:
    """Tuning of the matcher (defaults suit an RPLIDAR indoors, scans 0.1 s apart)."""

    max_iterations: int = 30
    #: Pairs farther apart than this are not correspondences (the largest motion expected between scans).
    max_correspondence_m: float = 0.5
    #: Robust outlier gate on the point-to-line residual, in robust standard deviations.
    reject_sigmas: float = 3.0
    #: The gate never goes below this (a near-perfect match must not reject its own noise).
    min_reject_m: float = 0.03
    #: Neighbours used to fit each target point's line.
    normal_neighbours: int = 10
    #: Two consecutive beams of a scan farther apart than this are on two surfaces (a jump in range): a point's
    #: line is fitted to the beams of its own run only (`IcpTarget.from_scan`).
    normal_max_gap_m: float = 0.3
    #: A target neighbourhood is a line when its smaller spread is below this fraction of the larger.
    max_planarity: float = 0.5
    #: A target point gets a line only when all its neighbours lie this close (m). On a dense target (a grid's
    #: occupied cells) a farther neighbour means no surface runs there: a table leg's ten nearest cells reach
    #: the next leg, and the "line" through both would pull the match. Scans (sparse far away) keep no limit.
    normal_radius_m: float = math.inf
    translation_tol_m: float = 5e-4
    rotation_tol_rad: float = 5e-4
    #: Fewer inliers than this and the result is not trusted.
    min_inliers: int = 10

    def __post_init__(self) -> None:
        if self.max_iterations < 1 or self.normal_neighbours < 2 or self.min_inliers < 3:
            raise ConfigError("icp: need max_iterations >= 1, normal_neighbours >= 2, min_inliers >= 3",
                              path="localization.icp")
        for name in ("max_correspondence_m", "reject_sigmas", "min_reject_m", "max_planarity", "normal_max_gap_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.icp.{name}")
        if not self.normal_radius_m > 0:  # inf: no limit; NaN fails too
            raise ConfigError(f"must be > 0, got {self.normal_radius_m!r}", path="localization.icp.normal_radius_m")


@dataclass(frozen=True)
class IcpResult:
    """The transform found and how much to believe it."""

    pose: Pose2D
    rmse_m: float
    inlier_fraction: float
    iterations: int
    converged: bool
    covariance: FloatArray = field(repr=False)

    @property
    def ok(self) -> bool:
        """Converged with a finite covariance: the caller may use ``pose``."""
        return self.converged and bool(np.all(np.isfinite(self.covariance)))


def _clean(points: FloatArray, what: str) -> FloatArray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ConfigError(f"icp: {what} points must have shape (M, 2), got {pts.shape}")
    with np.errstate(invalid="ignore"):
        return pts[(np.abs(pts) < MAX_COORD_M).all(axis=1)]  # drops NaN and inf too


class IcpTarget:
    """A reference point set prepared once: its k-d tree and per-point line normals.

    Matching many scans against one reference (the map's surfaces, a SLAM keyframe) pays for the tree
    and the normals once. An unordered set takes each point's line from its nearest neighbours (a k-d tree
    query); a scan, whose points come in beam order, from the beams beside each point (`from_scan`).
    """

    def __init__(self, points: FloatArray, params: IcpParams | None = None, *, beam_order: bool = False) -> None:
        self.params = p = params or IcpParams()
        self.points = _clean(points, "target")
        n = self.points.shape[0]
        self.tree = cKDTree(self.points) if n else None
        self.normals = np.full((n, 2), np.nan)
        if n < p.normal_neighbours:
            return
        if beam_order:
            count, cov = _beam_covariances(self.points, p.normal_neighbours, p.normal_max_gap_m)
            found = count >= max(3, p.normal_neighbours // 2)
        else:
            dist, nbr = self.tree.query(self.points, k=p.normal_neighbours)  # type: ignore[union-attr]
            found = (nbr < n).all(axis=1) & (dist[:, -1] <= p.normal_radius_m)
            nb = self.points[np.minimum(nbr, n - 1)]  # (n, k, 2)
            d = nb - nb.mean(axis=1, keepdims=True)
            cov = ((d[..., 0] ** 2).mean(axis=1), (d[..., 1] ** 2).mean(axis=1), (d[..., 0] * d[..., 1]).mean(axis=1))
        cxx, cyy, cxy = cov
        # eigenvalues of [[cxx, cxy], [cxy, cyy]]; the line's direction is the major axis
        half_tr, det_term = (cxx + cyy) / 2, np.sqrt(((cxx - cyy) / 2) ** 2 + cxy**2)
        major, minor = half_tr + det_term, half_tr - det_term
        ang = 0.5 * np.arctan2(2 * cxy, cxx - cyy)
        normals = np.column_stack([-np.sin(ang), np.cos(ang)])
        linear = found & (major > 1e-12) & (minor <= (p.max_planarity**2) * major)
        self.normals[linear] = normals[linear]

    @classmethod
    def from_scan(cls, points: FloatArray, params: IcpParams | None = None) -> IcpTarget:
        """A target of one scan's points in beam order (`atemr.skills.localization.scan.scan_points`): each
        point's line is fitted to the beams round it, ``normal_neighbours // 2`` on either side, within its run
        of beams (a jump of more than ``normal_max_gap_m`` between consecutive beams ends a run); a point with
        fewer than half that many (the end of a short run: a chair leg, clutter) has no normal."""
        return cls(points, params, beam_order=True)

    def __len__(self) -> int:
        return int(self.points.shape[0])


def _beam_covariances(points: FloatArray, k: int, max_gap_m: float
                      ) -> tuple[NDArray[np.intp], tuple[FloatArray, FloatArray, FloatArray]]:
    """For each point of a scan (beam order): how many beams its window holds, and their covariance (xx, yy,
    xy). The window is ``k // 2`` beams on either side and the point, cut at the ends of its run (consecutive
    beams at most ``max_gap_m`` apart). Window sums come from running totals: a few passes over the scan, where
    gathering every window would cost more than the k-d tree query it replaces."""
    n = points.shape[0]
    half = k // 2
    jump = np.hypot(*np.diff(points, axis=0).T) > max_gap_m
    run = np.concatenate([[0], np.cumsum(jump)])  # non-decreasing run number of each point
    first = np.searchsorted(run, run, side="left")
    last = np.searchsorted(run, run, side="right") - 1
    i = np.arange(n)
    lo, hi = np.maximum(i - half, first), np.minimum(i + half, last) + 1
    count = hi - lo
    x, y = (points - points.mean(axis=0)).T  # centred: the squares stay small, the differences exact enough

    def window(v: FloatArray) -> FloatArray:
        total = np.concatenate([[0.0], np.cumsum(v)])
        out: FloatArray = (total[hi] - total[lo]) / count
        return out

    mx, my = window(x), window(y)
    return count, (window(x * x) - mx * mx, window(y * y) - my * my, window(x * y) - mx * my)


def _median(values: FloatArray) -> float:
    """`np.median` of a 1-D array, the same number (the middle one, or the two middle ones' sum halved; NaN if
    any is NaN), from one `np.partition` without np.median's generic wrapping, a quarter of its cost: ICP takes
    two medians an iteration."""
    half = values.size // 2
    # numpy's mean of the middle ones sums from +0.0 (so a middle -0.0 comes out +0.0)
    if values.size % 2:
        part = np.partition(values, (half, -1))
        middle = 0.0 + float(part[half])
    else:
        part = np.partition(values, (half - 1, half, -1))
        middle = (0.0 + float(part[half - 1]) + float(part[half])) / 2.0
    return math.nan if math.isnan(part[-1]) else middle


def icp(
    source: FloatArray,
    target: FloatArray | IcpTarget,
    initial: Pose2D | None = None,
    params: IcpParams | None = None,
) -> IcpResult:
    """Align ``source`` onto ``target`` starting from ``initial``; see the module docstring.

    Never raises on poor data: too few points or inliers give ``converged=False`` and an infinite
    covariance, which every caller treats as "no measurement".
    """
    tgt = target if isinstance(target, IcpTarget) else IcpTarget(target, params)
    p = params or tgt.params
    src = _clean(source, "source")
    xf = as_array(initial or Pose2D())
    inf_cov = np.full((3, 3), np.inf)
    if len(tgt) < p.normal_neighbours or src.shape[0] < p.min_inliers or tgt.tree is None:
        return IcpResult(as_pose(xf), math.inf, 0.0, 0, False, inf_cov)
    converged = False
    rmse, inlier_fraction, cov = math.inf, 0.0, inf_cov
    last: tuple[FloatArray, FloatArray] | None = None
    it = 0
    for it in range(1, p.max_iterations + 1):
        moved = transform_points(xf, src)
        dist, idx = tgt.tree.query(moved, distance_upper_bound=p.max_correspondence_m)
        ok = np.isfinite(dist)
        idx_ok = np.where(ok, idx, 0)
        normals = tgt.normals[idx_ok]
        ok &= np.isfinite(normals[:, 0])
        if ok.sum() < p.min_inliers:
            return IcpResult(as_pose(xf), math.inf, float(ok.mean()), it, False, inf_cov)
        m, q, n = moved[ok], tgt.points[idx_ok[ok]], normals[ok]
        r = np.einsum("ij,ij->i", n, m - q)
        mad = _median(np.abs(r - _median(r)))
        gate = max(p.reject_sigmas * 1.4826 * mad, p.min_reject_m)
        keep = np.abs(r) <= gate
        if keep.sum() < p.min_inliers:
            return IcpResult(as_pose(xf), math.inf, float(keep.sum() / src.shape[0]), it, False, inf_cov)
        m, n, r = m[keep], n[keep], r[keep]
        # Rotation about the origin of the current frame: d(R p)/dθ = [-p_y, p_x].
        jac = np.column_stack([n[:, 0], n[:, 1], n[:, 1] * m[:, 0] - n[:, 0] * m[:, 1]])
        hess = jac.T @ jac
        try:
            delta = np.linalg.solve(hess, -jac.T @ r)
        except np.linalg.LinAlgError:
            return IcpResult(as_pose(xf), math.inf, float(keep.sum() / src.shape[0]), it, False, inf_cov)
        xf = compose(delta, xf)  # δ acts in the target frame, after xf
        inlier_fraction = float(keep.sum() / src.shape[0])
        last = (r, hess)
        if math.hypot(delta[0], delta[1]) < p.translation_tol_m and abs(delta[2]) < p.rotation_tol_rad:
            converged = True
            break
    if last is not None:  # the quality of the last step (only the result's own is ever read: not every step's)
        r, hess = last
        rmse = float(np.sqrt(np.mean(r**2)))
        sigma2 = float(r @ r) / max(1, r.size - 3)
        cov = sigma2 * np.linalg.pinv(hess)
    if converged and not np.all(np.isfinite(cov)):
        converged = False
    # The covariance is of the correction applied in the target frame at the converged pose; for the
    # small corrections at convergence that is the uncertainty of xf itself.
    return IcpResult(as_pose(xf), rmse, inlier_fraction, it, converged, cov)


__all__ = ["IcpParams", "IcpResult", "IcpTarget", "icp"]
