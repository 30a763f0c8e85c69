"""The localization pipeline against one map: AMCL + map EKF + covariance monitor + relocalization.

States: ``uninitialized`` (no pose yet) → ``global`` (global localization running) → ``localized`` ⇄
``lost`` (momentarily, while relocalizing). On every scan:

1. the map EKF moves by the odometry increment; AMCL updates when the robot moved enough;
2. while ``localized``: a fresh AMCL estimate corrects the map EKF, and the monitor checks the map
   pose's covariance and the scan's agreement with the map there. Lost → relocalize at once: a
   scan-to-map match around the last good pose (carried along by odometry since); if its agreement
   clears the limit AMCL restarts there with a tight cloud, otherwise global localization starts;
3. while ``global``: once AMCL's cloud is tight and the scan agrees with the map at its mean, the pose
   is refined by a scan-to-map match and the robot counts as localized.

Every change is recorded as an `LocalizationEvent` (the agent turns them into dashboard events and
0x153 bit 4). ``localized`` is False from "lost" until relocalization succeeds: the agent stops then.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from atemr.domain.maps import OccupancyMap
from atemr.errors import NavigationError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.amcl import Amcl, AmclParams, PoseEstimate
from atemr.skills.localization.covariance_monitor import CovarianceMonitor, MonitorParams, MonitorReport
from atemr.skills.localization.geometry import as_array, as_pose, compose, is_finite_pose, relative
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.odometry_ekf import MapEkf, MapEkfParams
from atemr.skills.localization.scan import scan_points
from atemr.skills.localization.scan_to_map import ScanToMapMatcher

State = Literal["uninitialized", "global", "localized", "lost"]
EventKind = Literal["initial_pose", "global_start", "localized", "lost", "relocalized"]


@dataclass(frozen=True)
class LocalizationEvent:
    """Something the operator should see: ``kind`` at time ``t``, with a human-readable ``detail``."""

    t: float
    kind: EventKind
    detail: str


@dataclass(frozen=True)
class LocalizerParams:
    """How AMCL, the monitor and relocalization are tuned."""

    amcl: AmclParams = field(default_factory=AmclParams)
    map_ekf: MapEkfParams = field(default_factory=MapEkfParams)
    monitor: MonitorParams = field(default_factory=MonitorParams)
    #: Local relocalization: search window around the last good pose.
    relocalize_window_m: float = 1.0
    relocalize_window_rad: float = 0.8
    #: A local match is accepted with at least this agreement (stricter than the monitor's limit: a wrong
    #: local match would hide a kidnapping, a refused one only costs a global localization).
    relocalize_min_agreement: float = 0.7
    #: Global localization counts as converged below these standard deviations.
    converged_std_xy_m: float = 0.15
    converged_std_yaw_rad: float = 0.15
    #: Cloud put round a matched pose (local relocalization, end of global localization).
    matched_std_m: float = 0.05
    matched_std_rad: float = 0.05
    #: Scans weighed without motion after a global start (the agent stops the robot while it is lost).
    global_static_updates: int = 30


class Localizer:
    """See the module docstring. ``rng`` seeds AMCL."""

    def __init__(self, grid: OccupancyMap, rng: np.random.Generator, params: LocalizerParams | None = None) -> None:
        self.params = p = params or LocalizerParams()
        self.map = grid
        self.field = LikelihoodField(grid, p.amcl.field)
        self.amcl = Amcl(grid, rng, p.amcl, self.field)
        self.matcher = ScanToMapMatcher(self.field)
        self.map_ekf = MapEkf(p.map_ekf)
        self.monitor = CovarianceMonitor(p.monitor)
        self.state: State = "uninitialized"
        self.events: list[LocalizationEvent] = []
        self.last_report: MonitorReport | None = None
        self._last_good: tuple[Pose2D, Pose2D] | None = None  # (map pose, odometry) when last known good
        self._odom: Pose2D | None = None
        #: An estimate waiting for the first odometry pose (the operator clicked before any scan arrived).
        self._pending: PoseEstimate | None = None
        self._static_updates = 0

    # -- operator ----------------------------------------------------------------------------------
    def set_initial_pose(self, now: float, pose: Pose2D, covariance: np.ndarray | None = None, *,
                         odom: Pose2D | None = None) -> None:
        """The operator's click: AMCL starts round ``pose``; refused (`NavigationError`) off the map's free space.

        ``odom``: the odometry pose at ``now``. With it the map pose holds from this moment; without it, from the
        next scan (until then the map→odom correction is the one before the click, and so is the map pose).
        """
        if not is_finite_pose(pose):
            raise NavigationError(f"initial pose must be finite, got {pose}")
        row, col = self.map.world_to_cell(pose.x_m, pose.y_m)
        if not self.map.contains(row, col) or not self.map.free[int(row), int(col)]:
            raise NavigationError(f"initial pose ({pose.x_m:.2f}, {pose.y_m:.2f}) is not in free space of the map")
        self.amcl.initialize(pose, covariance, now=now)
        if odom is not None and is_finite_pose(odom):
            self._odom = odom
        self._start_tracking(now, self.amcl.estimate)
        self._event(now, "initial_pose", f"initial pose ({pose.x_m:.2f}, {pose.y_m:.2f}, {pose.yaw_rad:.2f})")

    def start_global(self, now: float, why: str = "no initial pose") -> None:
        """Global localization over the whole map's free space."""
        self.amcl.initialize_global(now=now)
        self._static_updates = 0
        self.state = "global"
        self.monitor.reset()
        self._event(now, "global_start", f"global localization: {why}")

    # -- output ------------------------------------------------------------------------------------
    @property
    def localized(self) -> bool:
        return self.state == "localized"

    @property
    def estimate(self) -> PoseEstimate | None:
        """The map pose and its covariance, or None while not localized."""
        return self.map_ekf.estimate if self.localized else None

    def map_to_odom(self) -> Pose2D | None:
        return self.map_ekf.map_to_odom() if self.localized else None

    # -- per scan ----------------------------------------------------------------------------------
    def update(self, now: float, odom: Pose2D, scan: LaserScan) -> State:
        """Feed one scan with the odometry pose at its time; returns the state after it."""
        if self.state == "uninitialized" or not (math.isfinite(now) and is_finite_pose(odom)):
            return self.state
        self._odom = odom
        points = scan_points(scan)
        if self._pending is not None:
            self._anchor(self._pending, odom)
        elif self.map_ekf.initialized:
            self.map_ekf.predict(now, odom)
        if self.state == "global" and self._static_updates < self.params.global_static_updates:
            self.amcl.request_update()  # a stopped robot must still be able to find itself
            self._static_updates += 1
        ran = self.amcl.update(now, odom, points)
        if self.state == "global":
            if ran:
                self._check_global(now, odom, points)
            return self.state
        if ran:
            self.map_ekf.update(self.amcl.estimate)
        est = self.map_ekf.estimate
        agreement = float(self.field.agreement(as_array(est.pose)[None], points)[0]) if points.size else 0.0
        report = self.monitor.check(est, agreement)
        self.last_report = report
        if not report.reason:
            self._last_good = (est.pose, odom)
        if report.lost:
            self.state = "lost"
            self._event(now, "lost", report.reason)
            self._relocalize(now, odom, points)
        return self.state

    # -- internals ---------------------------------------------------------------------------------
    def _event(self, now: float, kind: EventKind, detail: str) -> None:
        self.events.append(LocalizationEvent(now, kind, detail))

    def _start_tracking(self, now: float, estimate: PoseEstimate) -> None:
        self.state = "localized"
        self.monitor.reset()
        if self._odom is None:
            self._pending = estimate
        else:
            self._anchor(estimate, self._odom)

    def _anchor(self, estimate: PoseEstimate, odom: Pose2D) -> None:
        """Tie a map pose to the odometry pose read at the same time (map EKF and last good pose)."""
        self._pending = None
        self.map_ekf.reset(estimate, odom)
        self._last_good = (estimate.pose, odom)

    def _matched(self, now: float, pose: Pose2D) -> PoseEstimate:
        p = self.params
        cov = np.diag([p.matched_std_m**2, p.matched_std_m**2, p.matched_std_rad**2])
        self.amcl.initialize(pose, cov, now=now)
        return PoseEstimate(now, pose, cov)

    def _check_global(self, now: float, odom: Pose2D, points: np.ndarray) -> None:
        p = self.params
        est = self.amcl.estimate
        if est.std_xy_m > p.converged_std_xy_m or est.std_yaw_rad > p.converged_std_yaw_rad or not points.size:
            return
        match = self.matcher.match(points, est.pose, window_xy_m=0.3, window_yaw_rad=0.3)
        if match.agreement < self.params.monitor.min_agreement:
            return
        self._start_tracking(now, self._matched(now, match.pose))
        self._event(now, "localized", f"global localization converged at ({match.pose.x_m:.2f}, "
                                      f"{match.pose.y_m:.2f}), {match.agreement:.0%} of the scan on the map")

    def _relocalize(self, now: float, odom: Pose2D, points: np.ndarray) -> None:
        p = self.params
        if self._last_good is not None and points.size:
            good_pose, good_odom = self._last_good
            guess = as_pose(compose(as_array(good_pose), relative(as_array(good_odom), as_array(odom))))
            match = self.matcher.match(points, guess, window_xy_m=p.relocalize_window_m,
                                       window_yaw_rad=p.relocalize_window_rad)
            if match.agreement >= max(p.monitor.min_agreement, p.relocalize_min_agreement):
                self._start_tracking(now, self._matched(now, match.pose))
                self._event(now, "relocalized", f"scan-to-map match near the last good pose at ({match.pose.x_m:.2f}, "
                                                f"{match.pose.y_m:.2f}), {match.agreement:.0%} on the map")
                return
        self.start_global(now, "the scan does not match the map near the last good pose")


__all__ = ["EventKind", "LocalizationEvent", "Localizer", "LocalizerParams", "State"]
