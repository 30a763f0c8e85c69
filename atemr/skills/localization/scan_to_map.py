"""Scan-to-map matching: where in the map does this scan fit, near a guess? (relocalization, SLAM)

Two stages, as in Cartographer's real-time correlative matcher followed by its refinement:

1. a brute-force correlative search over a window of poses around the guess (a grid in x, y and yaw),
   every candidate scored at once with the likelihood field (N poses × M points, one table look-up
   each), coarse first, then a finer window around the best coarse candidate;
2. point-to-line ICP of the scan against the map's surface points from the best candidate.

The result carries the scan's agreement with the map at the pose found, so the caller decides whether
the match is good enough (the covariance monitor compares it with its limit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.msgs import Pose2D
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, is_finite_pose
from atemr.skills.localization.icp import IcpParams, IcpTarget, icp
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.scan import evenly_spread


@dataclass(frozen=True)
class MapMatch:
    """Best pose found, its agreement with the map (0..1) and the mean per-point log-likelihood."""

    pose: Pose2D
    agreement: float
    score: float
    refined: bool


def pose_grid(center: FloatArray, half_xy_m: float, half_yaw_rad: float, step_xy_m: float,
              step_yaw_rad: float) -> FloatArray:
    """Candidate poses ``(K, 3)``: a regular grid around ``center`` (inclusive of the centre)."""
    nxy = max(0, math.floor(half_xy_m / step_xy_m + 1e-9))
    nth = max(0, math.floor(half_yaw_rad / step_yaw_rad + 1e-9))
    d = np.arange(-nxy, nxy + 1) * step_xy_m
    a = np.arange(-nth, nth + 1) * step_yaw_rad
    dx, dy, dth = np.meshgrid(d, d, a, indexing="ij")
    return np.column_stack([center[0] + dx.ravel(), center[1] + dy.ravel(), center[2] + dth.ravel()])


class ScanToMapMatcher:
    """Matches base-frame scan points against one map (its likelihood field and surface points)."""

    def __init__(self, field: LikelihoodField, icp_params: IcpParams | None = None, *,
                 max_points: int = 90, chunk_poses: int = 20_000) -> None:
        self.field = field
        self.icp_params = icp_params or IcpParams(max_correspondence_m=0.3)
        self.target = IcpTarget(field.obstacle_points(), self.icp_params)
        self.max_points = max_points
        self.chunk_poses = chunk_poses

    def _best(self, candidates: FloatArray, pts: FloatArray) -> tuple[FloatArray, float]:
        best_i, best_s, best_pose = -1, -math.inf, candidates[0]
        for start in range(0, candidates.shape[0], self.chunk_poses):  # bounded memory, not a loop per pose
            chunk = candidates[start:start + self.chunk_poses]
            s = self.field.log_likelihood(chunk, pts)
            i = int(np.argmax(s))
            if s[i] > best_s:
                best_i, best_s, best_pose = start + i, float(s[i]), chunk[i]
        assert best_i >= 0
        return best_pose, best_s

    def match(
        self,
        points: FloatArray,
        guess: Pose2D,
        *,
        window_xy_m: float = 0.5,
        window_yaw_rad: float = 0.5,
        refine: bool = True,
    ) -> MapMatch:
        """The best pose within ``±window`` of ``guess`` for the scan ``points`` (base frame).

        Raises `ConfigError` for a non-finite guess or window (a caller bug, not a sensor glitch); an
        empty scan gives agreement 0 at the guess.
        """
        if not is_finite_pose(guess) or not (math.isfinite(window_xy_m) and math.isfinite(window_yaw_rad)):
            raise ConfigError(f"scan-to-map: guess and window must be finite, got {guess}, {window_xy_m}, "
                              f"{window_yaw_rad}", path="localization.match")
        pts_all = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        pts_all = pts_all[np.isfinite(pts_all).all(axis=1)]
        if pts_all.shape[0] == 0:
            return MapMatch(guess, 0.0, -math.inf, False)
        sel = evenly_spread(pts_all.shape[0], min(self.max_points, pts_all.shape[0]))
        pts = pts_all[sel]
        res = self.field.map.resolution_m
        center = as_array(guess)
        # Coarse: steps of 2 cells and a yaw step that moves the farthest point by about 2 cells.
        far = float(np.max(np.hypot(pts[:, 0], pts[:, 1]))) or 1.0
        step_xy = max(2 * res, window_xy_m / 12)
        step_yaw = max(min(2 * res / far, 0.05), window_yaw_rad / 40)
        best, _ = self._best(pose_grid(center, window_xy_m, window_yaw_rad, step_xy, step_yaw), pts)
        # Fine: one coarse step around the best, at a quarter of the step.
        best, score = self._best(pose_grid(best, step_xy, step_yaw, step_xy / 4, step_yaw / 4), pts)
        refined = False
        if refine:
            result = icp(pts_all, self.target, as_pose(best), self.icp_params)
            if result.ok:
                cand = as_array(result.pose)
                s = float(self.field.log_likelihood(cand[None], pts)[0])
                # Keep the refinement unless it made the fit to the field clearly worse.
                if s >= score - 0.5 * pts.shape[0] * 0.05:
                    best, score, refined = cand, s, True
        agreement = float(self.field.agreement(best[None], pts_all)[0])
        return MapMatch(as_pose(best), agreement, score / pts.shape[0], refined)


__all__ = ["MapMatch", "ScanToMapMatcher", "pose_grid"]
