"""Covariance monitor and the localization pipeline: lost → relocalized, kidnapped robot, global start, RMSE."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atemr.errors import ConfigError, NavigationError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.amcl import PoseEstimate
from atemr.skills.localization.covariance_monitor import CovarianceMonitor, MonitorParams
from atemr.skills.localization.localizer import Localizer


def est(std_xy: float = 0.05, std_yaw: float = 0.05) -> PoseEstimate:
    return PoseEstimate(0.0, Pose2D(), np.diag([std_xy**2, std_xy**2, std_yaw**2]))


@pytest.mark.parametrize(("estimate", "agreement", "reason"), [
    (est(), 0.9, ""),
    (est(std_xy=0.8), 0.9, "position uncertainty 0.80 m"),
    (est(std_yaw=0.5), 0.9, "heading uncertainty 29°"),
    (est(), 0.3, "scan agrees with the map for 30%"),
    (est(), float("nan"), "scan agrees with the map for"),
    (PoseEstimate(0.0, Pose2D(), np.full((3, 3), np.nan)), 0.9, "pose covariance is not finite"),
])
def test_reasons(estimate: PoseEstimate, agreement: float, reason: str) -> None:
    m = CovarianceMonitor(MonitorParams(lost_after=1))
    report = m.check(estimate, agreement)
    assert report.reason.startswith(reason) if reason else report.reason == ""
    assert report.lost == bool(reason)


def test_lost_only_after_consecutive_bad_checks() -> None:
    m = CovarianceMonitor(MonitorParams(lost_after=3))
    assert [m.check(est(), a).lost for a in (0.2, 0.2, 0.9, 0.2, 0.2)] == [False] * 5  # a person walked past
    assert m.check(est(), 0.2).lost
    with pytest.raises(ConfigError):
        MonitorParams(min_agreement=1.5)


def run(loc: Localizer, rec, start: int = 0) -> list[tuple[int, str, float | None]]:  # type: ignore[no-untyped-def]
    out: list[tuple[int, str, float | None]] = []
    for i in range(start, len(rec.scans)):
        state = loc.update(rec.scans[i].t, rec.odom[i], rec.scans[i])
        e = loc.estimate
        out.append((i, state, None if e is None else e.pose.distance_to(rec.truth[i])))
    return out


def test_kidnapped_robot_is_noticed_and_relocalized(studio_map, simdrive) -> None:  # type: ignore[no-untyped-def]
    """Teleported 1.9 m at t = 8 s while driving: lost within three scans, then global localization finds it."""
    rec = simdrive.drive(seed=4, kidnap=(8.0, Pose2D(2.45, 3.0, -math.pi / 2)), max_s=20.0)
    loc = Localizer(studio_map, np.random.default_rng(0))
    loc.set_initial_pose(0.0, rec.truth[0])
    out = run(loc, rec)
    kinds = [e.kind for e in loc.events]
    assert kinds[:4] == ["initial_pose", "lost", "global_start", "localized"], loc.events
    lost = loc.events[1]
    assert 8.0 < lost.t <= 8.35 and "agrees with the map" in lost.detail
    back = loc.events[3].t
    assert back - lost.t < 3.0
    errors = [e for i, s, e in out if rec.scans[i].t > back]
    assert errors and max(e for e in errors if e is not None) < 0.1
    assert all(s == "localized" for i, s, _ in out if rec.scans[i].t < 8.0 or rec.scans[i].t > back)


def test_small_slip_is_relocalized_locally(studio_map, simdrive) -> None:  # type: ignore[no-untyped-def]
    """A 0.5 m jump (a bump, a wheel lifted) is found again by scan-to-map matching, without going global."""
    rec = simdrive.drive(seed=5, max_s=12.0)
    t = rec.truth[50]
    loc2 = Localizer(studio_map, np.random.default_rng(1))
    loc2.set_initial_pose(rec.scans[50].t, Pose2D(t.x_m + 0.45, t.y_m - 0.2, t.yaw_rad + 0.2),
                          np.diag([1e-4, 1e-4, 1e-4]))  # confidently wrong
    out = run(loc2, rec, 50)
    kinds = [e.kind for e in loc2.events]
    assert "lost" in kinds and "relocalized" in kinds and "global_start" not in kinds
    assert out[-1][1] == "localized" and out[-1][2] is not None and out[-1][2] < 0.1


def test_global_start_and_pose_rmse(studio_map, living_room_drive) -> None:  # type: ignore[no-untyped-def]
    """From no pose at all: global localization, then the map pose tracks the truth with RMSE < 0.10 m."""
    rec = living_room_drive
    loc = Localizer(studio_map, np.random.default_rng(3))
    loc.start_global(0.0)
    assert loc.estimate is None and not loc.localized
    out = run(loc, rec)
    errors = np.array([e for _, s, e in out if e is not None])
    assert loc.localized and errors.size > 0.8 * len(out)
    rmse = float(np.sqrt(np.mean(errors**2)))
    assert rmse < 0.10, rmse


def test_initial_pose_is_validated(studio_map) -> None:  # type: ignore[no-untyped-def]
    loc = Localizer(studio_map, np.random.default_rng(0))
    with pytest.raises(NavigationError, match="free space"):
        loc.set_initial_pose(0.0, Pose2D(0.5, 2.0, 0.0))  # inside the sofa
    with pytest.raises(NavigationError, match="free space"):
        loc.set_initial_pose(0.0, Pose2D(50.0, 2.0, 0.0))
    with pytest.raises(NavigationError, match="finite"):
        loc.set_initial_pose(0.0, Pose2D(float("nan"), 2.0, 0.0))
    assert loc.state == "uninitialized" and loc.estimate is None


def test_global_localization_of_a_robot_standing_still(studio_map) -> None:  # type: ignore[no-untyped-def]
    """The agent stops a lost robot: global localization must still converge from scans alone (no-motion updates)."""
    from atemr.clock import SimClock
    from atemr.io.sim.simulation import build_simulation
    from atemr.scheduler import Scheduler

    sim = build_simulation("studio", 2)
    sim.kidnap(Pose2D(7.5, 3.0, 2.0))  # in the bedroom
    sched = Scheduler(SimClock())
    sim.attach(sched)
    scans: list[LaserScan] = []
    sim.lidar_source.subscribe(scans.append)
    sched.run(until=2.0)
    loc = Localizer(studio_map, np.random.default_rng(2))
    loc.start_global(0.0)
    for scan in scans:
        loc.update(scan.t, sim.odometry, scan)
    e = loc.estimate
    assert loc.localized and e is not None and e.pose.distance_to(sim.pose) < 0.1
    assert [ev.kind for ev in loc.events] == ["global_start", "localized"]
