"""The confidence monitor and the localizer: lost → relocalized, kidnapped robot, global start, RMSE, the
operator's pose checked against the scan."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atemr.errors import ConfigError, NavigationError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.amcl import PoseEstimate
from atemr.skills.localization.covariance_monitor import CovarianceMonitor, MonitorParams, robust_agreement
from atemr.skills.localization.localizer import Localizer
from atemr.skills.localization.map_agreement import ScanAgreement


def est(std_xy: float = 0.05, std_yaw: float = 0.05, t: float = 0.0) -> PoseEstimate:
    return PoseEstimate(t, Pose2D(), np.diag([std_xy**2, std_xy**2, std_yaw**2]))


def counts(hits: int, through: int = 0, unexplained: int = 0) -> ScanAgreement:
    return ScanAgreement(np.array([hits]), np.array([through]), np.array([unexplained]))


@pytest.mark.parametrize(("estimate", "scan", "reason"), [
    (est(), counts(95, 0, 5), ""),
    (est(std_xy=0.8), counts(100), "position uncertainty 0.80 m"),
    (est(std_yaw=0.5), counts(100), "heading uncertainty 29°"),
    (est(), counts(30, 40, 30), "scan agrees with the map for 40% (of 100 beams: 30 on the map, 40 through walls"),
    (est(), counts(0), "scan agrees with the map for 0%"),
    (PoseEstimate(0.0, Pose2D(), np.full((3, 3), np.nan)), counts(100), "pose covariance is not finite"),
])
def test_evidence_and_its_reasons(estimate: PoseEstimate, scan: ScanAgreement, reason: str) -> None:
    m = CovarianceMonitor()
    report = m.check(estimate, scan)  # the first check sets the confidence to its evidence
    assert (reason in report.reason) if reason else report.reason == ""
    assert report.lost == bool(reason) and report.confidence == report.evidence


def test_unmapped_obstacles_may_hide_a_quarter_of_the_scan_and_walls_always_count() -> None:
    assert robust_agreement(counts(75, 0, 25), 0.25) == 1.0  # people and a chair in front of a quarter of it
    assert robust_agreement(counts(60, 0, 40), 0.25) == pytest.approx(60 / 75)  # beyond that, they count
    assert robust_agreement(counts(75, 25, 0), 0.25) == 0.75  # seeing through walls is never excused
    assert robust_agreement(counts(0), 0.25) == 0.0


def test_confidence_is_averaged_over_time_not_scans() -> None:
    m = CovarianceMonitor(MonitorParams(time_constant_s=1.0))
    m.reset(0.98, 0.0)
    report = m.check(est(t=0.1), counts(20, 40, 40))  # one bad scan: a person right in front of the lidar
    assert not report.lost and report.confidence > 0.8 and report.evidence < 0.3
    t = 0.1
    while not report.lost:  # the bad view persists: a kidnapped robot
        t += 0.1
        report = m.check(est(t=t), counts(20, 40, 40))
    assert 0.4 < t < 1.5 and "confidence" in report.reason and "through walls" in report.reason
    with pytest.raises(ConfigError, match="min_confidence"):
        MonitorParams(min_confidence=1.5)
    with pytest.raises(ConfigError, match="unmapped_allowance"):
        MonitorParams(unmapped_allowance=-0.1)


def run(loc: Localizer, rec, start: int = 0) -> list[tuple[int, str, float | None]]:  # type: ignore[no-untyped-def]
    out: list[tuple[int, str, float | None]] = []
    for i in range(start, len(rec.scans)):
        state = loc.update(rec.scans[i].t, rec.odom[i], rec.scans[i])
        e = loc.estimate
        out.append((i, state, None if e is None else e.pose.distance_to(rec.truth[i])))
    return out


def test_kidnapped_robot_is_noticed_and_relocalized(studio_map, simdrive) -> None:  # type: ignore[no-untyped-def]
    """Teleported 1.9 m at t = 8 s while driving: lost within half a second, then global localization finds it."""
    rec = simdrive.drive(seed=4, kidnap=(8.0, Pose2D(2.45, 3.0, -math.pi / 2)), max_s=20.0)
    loc = Localizer(studio_map, np.random.default_rng(0))
    loc.set_initial_pose(0.0, rec.truth[0])
    out = run(loc, rec)
    kinds = [e.kind for e in loc.events]
    assert kinds[:5] == ["initial_pose", "localized", "lost", "global_start", "localized"], loc.events
    lost = loc.events[2]
    assert 8.0 < lost.t <= 8.5 and "agrees with the map" in lost.detail
    back = loc.events[4].t
    assert back - lost.t < 3.0
    errors = [e for i, s, e in out if rec.scans[i].t > back]
    assert errors and max(e for e in errors if e is not None) < 0.1
    assert all(s == "localized" for i, s, _ in out if rec.scans[i].t < 8.0 or rec.scans[i].t > back)


def test_small_slip_is_relocalized_locally(studio_map, simdrive) -> None:  # type: ignore[no-untyped-def]
    """A 0.6 m jump (a bump, a wheel lifted) is found again by scan-to-map matching, without going global."""
    t = 6.0
    rec = simdrive.drive(seed=5, max_s=12.0, kidnap=None)
    slip = rec.truth[int(t * 10)]
    rec = simdrive.drive(seed=5, max_s=12.0, kidnap=(t, Pose2D(slip.x_m + 0.5, slip.y_m - 0.3, slip.yaw_rad + 0.2)))
    loc = Localizer(studio_map, np.random.default_rng(1))
    loc.set_initial_pose(0.0, rec.truth[0])
    out = run(loc, rec)
    kinds = [e.kind for e in loc.events]
    assert "lost" in kinds and "relocalized" in kinds and "global_start" not in kinds, loc.events
    assert out[-1][1] == "localized" and out[-1][2] is not None and out[-1][2] < 0.1


def test_an_operators_pose_is_checked_against_the_scan(studio_map, living_room_drive) -> None:  # type: ignore[no-untyped-def]
    """A click a little off is matched onto the map; a click in the wrong room is refused and the robot
    searches the whole map instead of believing it (the scan, not the click, decides)."""
    rec = living_room_drive
    truth = rec.truth[0]
    near = Localizer(studio_map, np.random.default_rng(0))
    near.set_initial_pose(0.0, Pose2D(truth.x_m + 0.3, truth.y_m - 0.2, truth.yaw_rad + 0.15))
    assert not near.localized and near.state == "pose set" and near.confidence == 0.0
    near.update(rec.scans[0].t, rec.odom[0], rec.scans[0])
    e = near.estimate
    assert near.localized and e is not None and e.pose.distance_to(truth) < 0.05
    assert near.confidence >= 0.9 and [ev.kind for ev in near.events] == ["initial_pose", "localized"]

    wrong = Localizer(studio_map, np.random.default_rng(0))
    wrong.set_initial_pose(0.0, Pose2D(7.5, 5.5, 0.0))  # the bedroom
    wrong.update(rec.scans[0].t, rec.odom[0], rec.scans[0])
    kinds = [ev.kind for ev in wrong.events]
    assert kinds == ["initial_pose", "pose_refused", "global_start", "localized"], wrong.events
    assert "does not match the map near the pose set" in wrong.events[1].detail
    e = wrong.estimate
    assert wrong.localized and e is not None and e.pose.distance_to(truth) < 0.1


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
    assert loc.result is not None and loc.result.outcome == "localized" and loc.confidence >= 0.7
