"""The localization pipeline against one map: global search, AMCL + map EKF, the confidence monitor, relocalization.

Phases (`Phase`), each with its own method, run on every scan:

* ``UNINITIALIZED``: no pose yet (a map just selected): nothing to do until a pose is set or searched for.
* ``POSE_SET``: the operator gave a pose; the next scan is matched to the map near it (± 0.5 m, ± 20°). If
  the scan agrees there the robot tracks from the matched pose, otherwise the pose is refused (an event
  says how much of the scan agreed) and the robot searches the whole map.
* ``SEARCHING``: global localization (`GlobalSearch`) on the next scan, three outcomes: *localized* → tracking;
  *ambiguous* → the candidate places are kept; *failed* → searched again later.
* ``AMBIGUOUS``: every candidate is carried along by odometry; each time the robot has moved or turned
  enough for a new view, the candidates are refined on the new scan and its beams pooled with the earlier
  ones, until one place is clearly best (tracking from there), or none explains the scans (a new search).
* ``FAILED``: searched again once the robot has moved, or after ``retry_s``.
* ``TRACKING``: AMCL updates when the robot moved enough and corrects the map EKF. A robot that stands still is
  not matched to anything: its odometry stands still too (the odometry EKF takes the gyro's bias out, learned while
  the wheels stand), so its map pose has nothing to drift by. The monitor turns every scan into evidence and the
  evidence into the **confidence** (`CovarianceMonitor`), standing or not: one look at the scan from the current pose,
  no search. Below the limit the robot is lost (a robot carried off while its wheels stood still is noticed here): a
  scan-to-map match near the last good pose (carried along by odometry), accepted if the scan agrees there, else a
  global search on the same scan.

``localized`` means tracking with the confidence at or above ``monitor.min_confidence``, nothing else; the
confidence is the one number every consumer shows (dashboard, CAN 0x153 bit 4, ``mission run --json``, the
agent's guards). Outside tracking it is the search's own (`GlobalResult.confidence`), or 0.

A scan without a single valid return (a covered or glitched lidar) is no evidence for or against any pose:
no phase acts on it, and while tracking the pose follows odometry alone (a lidar that stays blind is the
health board's to report, not localization's).

Every change is an `LocalizationEvent` (the dashboard's event list).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Literal

import numpy as np

from atemr.domain.maps import OccupancyMap
from atemr.domain.status import LocalizationState
from atemr.errors import NavigationError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.diff_drive import wrap_angle
from atemr.skills.localization.amcl import Amcl, AmclParams, PoseEstimate
from atemr.skills.localization.covariance_monitor import (
    CovarianceMonitor,
    MonitorParams,
    MonitorReport,
    robust_agreement,
)
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, compose, is_finite_pose, relative
from atemr.skills.localization.global_search import (
    GlobalResult,
    GlobalSearch,
    GlobalSearchParams,
    Hypotheses,
    Hypothesis,
)
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.map_agreement import AgreementParams, MapAgreement
from atemr.skills.localization.odometry_ekf import MapEkf, MapEkfParams
from atemr.skills.localization.scan import open_ray_ends, scan_points, sensor_origin
from atemr.skills.localization.scan_to_map import MapMatch, ScanToMapMatcher

EventKind = Literal["initial_pose", "pose_refused", "global_start", "localized", "ambiguous", "failed", "lost",
                    "relocalized", "map_changed"]


#: An operator's pose that fits the scan within this share of the best match nearby is kept as it was given
#: (a pose from mapping, or typed exactly, is not moved by the match's own few centimetres).
POSE_KEPT_WITHIN = 0.01
#: An operator's ambiguous search stops asking to look around once the robot has turned this far (rad): a whole
#: revolution, less a few scans of the turn (the view at the starting heading again adds little).
LOOKED_ROUND_RAD = 2 * math.pi - 0.2
#: ... or once this long has passed since the operator asked (s), whatever held the robot (a safety stop, blocked
#: wheels): a look never stays asked for, to start again later when nobody expects it.
LOOK_TIMEOUT_S = 30.0


class Phase(Enum):
    """What the localizer does with the next scan (module docstring)."""

    UNINITIALIZED = "uninitialized"
    POSE_SET = "pose set"
    SEARCHING = "searching"
    AMBIGUOUS = "ambiguous"
    FAILED = "failed"
    TRACKING = "tracking"


#: What each phase but tracking shows as the localization state (tracking shows localized or lost).
_PHASE_STATES: dict[Phase, LocalizationState] = {
    Phase.UNINITIALIZED: "uninitialized", Phase.POSE_SET: "pose set", Phase.SEARCHING: "searching",
    Phase.AMBIGUOUS: "ambiguous", Phase.FAILED: "failed",
}


@dataclass(frozen=True)
class LocalizationEvent:
    """Something the operator should see: ``kind`` at time ``t``, with a human-readable ``detail``."""

    t: float
    kind: EventKind
    detail: str


@dataclass(frozen=True)
class LocalizerParams:
    """How AMCL, the monitor, the searches and relocalization are tuned."""

    amcl: AmclParams = field(default_factory=AmclParams)
    map_ekf: MapEkfParams = field(default_factory=MapEkfParams)
    monitor: MonitorParams = field(default_factory=MonitorParams)
    agreement: AgreementParams = field(default_factory=AgreementParams)
    global_search: GlobalSearchParams = field(default_factory=GlobalSearchParams)
    #: Local relocalization: search window around the last good pose.
    relocalize_window_m: float = 1.0
    relocalize_window_rad: float = 0.8
    #: An operator's pose is matched to the map within this window.
    pose_window_m: float = 0.5
    pose_window_rad: float = 0.35
    #: Cloud put round a matched pose (a checked operator's pose, a relocalization, a global search's answer).
    matched_std_m: float = 0.05
    matched_std_rad: float = 0.05
    #: While ambiguous, a scan adds evidence once the robot moved or turned this much since the last one.
    evidence_every_m: float = 0.3
    evidence_every_rad: float = math.radians(45.0)
    #: After a failed search: search again after this long, or once the robot moved as above.
    retry_s: float = 5.0


class Localizer:
    """See the module docstring. ``rng`` seeds AMCL."""

    def __init__(self, grid: OccupancyMap, rng: np.random.Generator, params: LocalizerParams | None = None) -> None:
        self.params = p = params or LocalizerParams()
        self.map = grid
        self.field = LikelihoodField(grid, p.amcl.field)
        self.agreement = MapAgreement(self.field, p.agreement)
        self.search = GlobalSearch(self.field, self.agreement, p.global_search)
        self.amcl = Amcl(grid, rng, p.amcl, self.field)
        self.matcher = ScanToMapMatcher(self.field)
        self.map_ekf = MapEkf(p.map_ekf)
        self.monitor = CovarianceMonitor(p.monitor)
        self.phase = Phase.UNINITIALIZED
        self.events: list[LocalizationEvent] = []
        self.last_report: MonitorReport | None = None
        #: The last global search's answer (None before the first).
        self.result: GlobalResult | None = None
        self._hypotheses: Hypotheses | None = None
        #: The latest scan's open beams (`open_ray_ends`), base frame.
        self._opens: FloatArray = np.zeros((0, 2))
        self._search_confidence = 0.0
        self._prior: tuple[Pose2D, Pose2D | None] | None = None  # operator's pose, odometry when it was given
        self._last_good: tuple[Pose2D, Pose2D] | None = None  # (map pose, odometry) when last known good
        self._mark: tuple[float, Pose2D] | None = None  # (time, odometry) of the last view while not tracking
        self._odom: Pose2D | None = None  # the odometry of the latest scan
        self._look_around = False  # the current search was the operator's, who asked the robot to look around
        self._look_turned = 0.0  # how far it has turned since (rad, from the odometry)
        self._look_since = 0.0  # when the operator asked

    # -- operator ----------------------------------------------------------------------------------
    def set_initial_pose(self, now: float, pose: Pose2D, covariance: np.ndarray | None = None, *,
                         odom: Pose2D | None = None) -> None:
        """The operator's click: checked against the next scan (`Phase.POSE_SET`); refused at once
        (`NavigationError`) off the map's free space.

        ``odom``: the odometry pose at ``now`` (the robot may move before the next scan). ``covariance`` is
        accepted for compatibility and unused: the pose is matched to the map, not trusted as it is.
        """
        del covariance
        if not is_finite_pose(pose):
            raise NavigationError(f"initial pose must be finite, got {pose}")
        row, col = self.map.world_to_cell(pose.x_m, pose.y_m)
        if not self.map.contains(row, col) or not self.map.free[int(row), int(col)]:
            raise NavigationError(f"initial pose ({pose.x_m:.2f}, {pose.y_m:.2f}) is not in free space of the map")
        self._prior = (pose, odom if odom is not None and is_finite_pose(odom) else None)
        self._look_around = False
        self._enter(Phase.POSE_SET, 0.0)
        self._event(now, "initial_pose", f"initial pose ({pose.x_m:.2f}, {pose.y_m:.2f}, {pose.yaw_rad:.2f}) set; "
                                         "checking it against the next scan")

    def start_global(self, now: float, why: str = "no initial pose", *, look_around: bool = False) -> None:
        """Global localization over the whole map, on the next scan. ``look_around``: the operator asked the robot
        to find itself (FIND POSITION), so while the answer is ambiguous it may turn in place to see more
        (`wants_a_look`); a search the robot starts by itself never moves it in MANUAL."""
        self._enter(Phase.SEARCHING, 0.0)
        self._look_around, self._look_turned, self._look_since = look_around, 0.0, now
        self._event(now, "global_start", f"global localization: {why}")

    def stop_looking(self) -> None:
        """The operator took over (the joystick, STOP, mapping): the robot no longer turns by itself for this
        search. The views it gathers while driven are pooled all the same."""
        self._look_around = False

    @property
    def wants_a_look(self) -> bool:
        """Whether the operator's search is ambiguous, so the robot should turn in place to tell the places apart
        (the views it gathers meanwhile are pooled: `Hypotheses.add_scan`)."""
        return self._look_around and self.phase is Phase.AMBIGUOUS

    # -- output ------------------------------------------------------------------------------------
    @property
    def confidence(self) -> float:
        """The one number: the monitor's while tracking, the last search's while searching, else 0."""
        return self.monitor.confidence if self.phase is Phase.TRACKING else self._search_confidence

    @property
    def localized(self) -> bool:
        """The confidence at or above the limit, nothing else (outside tracking it never is: an ambiguous
        search shares its evidence among at least two places, and the limit is above one half)."""
        return self.confidence >= self.params.monitor.min_confidence

    @property
    def state(self) -> LocalizationState:
        """``localized``, ``lost`` (tracking below the limit), or the phase's name."""
        if self.phase is Phase.TRACKING:
            return "localized" if self.localized else "lost"
        return _PHASE_STATES[self.phase]

    @property
    def candidates(self) -> tuple[Hypothesis, ...]:
        """The places under consideration while ambiguous (best first, carried along to the latest odometry),
        else ()."""
        hyps = self._hypotheses
        if self.phase is not Phase.AMBIGUOUS or hyps is None:
            return ()
        if self._odom is None:
            return hyps.ranked()
        return hyps.ranked(relative(hyps.first_odom, as_array(self._odom)))

    @property
    def estimate(self) -> PoseEstimate | None:
        """The map pose and its covariance, or None while not localized."""
        return self.map_ekf.estimate if self.localized else None

    def map_to_odom(self) -> Pose2D | None:
        return self.map_ekf.map_to_odom() if self.localized else None

    # -- per scan ----------------------------------------------------------------------------------
    def update(self, now: float, odom: Pose2D, scan: LaserScan, *, points: FloatArray | None = None) -> str:
        """Feed one scan with the odometry pose at its time; returns `state` after it. ``points``: the scan's
        `scan_points`, when the caller made them already."""
        if not (math.isfinite(now) and is_finite_pose(odom)):
            return self.state
        points, sensor = scan_points(scan) if points is None else points, sensor_origin(scan)
        self._opens = open_ray_ends(scan)  # global localization's evidence besides the returns
        if self.wants_a_look and self._odom is not None:
            self._look_turned += abs(float(wrap_angle(odom.yaw_rad - self._odom.yaw_rad)))
        self._odom = odom
        if self.wants_a_look and (self._look_turned >= LOOKED_ROUND_RAD or now - self._look_since >= LOOK_TIMEOUT_S):
            self._look_around = False  # a whole turn has shown all a turn can: the operator decides now
            done = "turned once round" if self._look_turned >= LOOKED_ROUND_RAD else \
                f"looked around for {LOOK_TIMEOUT_S:g} s"
            self._event(now, "ambiguous", f"global localization: {done} and the places still look alike; drive the "
                                          "robot or set its position")
        if self.phase is Phase.TRACKING:
            self.map_ekf.predict(now, odom)
        if not len(points):  # no valid return (a blind or glitched scan): no evidence for or against any pose
            return self.state
        if self.phase is Phase.TRACKING:
            self._track(now, odom, points, sensor)
        elif self.phase is Phase.POSE_SET:
            self._check_pose(now, odom, points, sensor)
        elif self.phase is Phase.SEARCHING:
            self._search(now, odom, points, sensor)
        elif self.phase is Phase.AMBIGUOUS:
            self._gather(now, odom, points, sensor)
        elif self.phase is Phase.FAILED:
            self._retry(now, odom, points, sensor)
        return self.state

    # -- phases ------------------------------------------------------------------------------------
    def _check_pose(self, now: float, odom: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> None:
        assert self._prior is not None
        pose, at = self._prior
        if at is not None:
            pose = as_pose(compose(as_array(pose), relative(as_array(at), as_array(odom))))
        p = self.params
        match = self.matcher.match(points, pose, window_xy_m=p.pose_window_m, window_yaw_rad=p.pose_window_rad)
        value, given = self._fit(match.pose, points, sensor), self._fit(pose, points, sensor)
        if given >= value - POSE_KEPT_WITHIN:  # a pose that fits as well as the match is kept as given
            match, value = MapMatch(pose, match.agreement, match.score, False), given
        if value >= p.monitor.min_confidence:
            self._track_from(now, match.pose, odom, value)
            self._event(now, "localized", f"initial pose checked: {value:.0%} of the scan on the map at "
                                          f"{_where(match.pose)}")
            return
        self._event(now, "pose_refused", f"the scan does not match the map near the pose set: at best {value:.0%} of "
                                         f"it agrees (at {_where(match.pose)}), below {p.monitor.min_confidence:.0%}")
        self.start_global(now, "the pose set does not match the scan")
        self._search(now, odom, points, sensor)

    def _search(self, now: float, odom: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> None:
        result, hypotheses = self.search.search(points, sensor, as_array(odom), self._opens)
        self.result = result
        if result.outcome == "localized" and result.pose is not None:
            self._track_from(now, result.pose, odom, result.confidence)
            self._event(now, "localized", f"global localization: {result.reason}")
            return
        self._mark = (now, odom)
        if result.outcome == "ambiguous":
            hypotheses.keep(hypotheses.agreement >= self.params.monitor.min_confidence)
            self._hypotheses = hypotheses
            self._enter(Phase.AMBIGUOUS, result.confidence)
            todo = "turning in place to tell them apart" if self._look_around else "move the robot to tell them apart"
            self._event(now, "ambiguous", f"global localization: {result.reason}; {todo}")
        else:
            self._enter(Phase.FAILED, result.confidence)
            self._event(now, "failed", f"global localization: {result.reason}")

    def _moved(self, odom: Pose2D) -> bool:
        """Whether the robot moved or turned enough since the last view for a new one to tell more."""
        if self._mark is None:
            return True
        p = self.params
        d = relative(as_array(self._mark[1]), as_array(odom))
        return math.hypot(d[0], d[1]) >= p.evidence_every_m or abs(float(d[2])) >= p.evidence_every_rad

    def _gather(self, now: float, odom: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> None:
        hyps = self._hypotheses
        if hyps is None or not self._moved(odom):
            return
        self._mark = (now, odom)
        hyps.add_scan(points, sensor, relative(hyps.first_odom, as_array(odom)), self._opens)
        hyps.keep(hyps.agreement >= self.params.monitor.min_confidence)
        result = hyps.decide()
        self.result = result
        if result.outcome == "localized" and result.pose is not None:
            self._track_from(now, result.pose, odom, float(self._fit(result.pose, points, sensor)))
            self._event(now, "localized", f"after {len(hyps.hits)} views: {result.reason}")
        elif result.outcome == "failed":
            self.start_global(now, "no candidate place explains the new views")
        else:
            self._search_confidence = result.confidence

    def _retry(self, now: float, odom: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> None:
        if self._mark is None or self._moved(odom) or now - self._mark[0] >= self.params.retry_s:
            self._search(now, odom, points, sensor)

    def _track(self, now: float, odom: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> None:
        p = self.params
        if self.amcl.update(now, odom, points):
            self.map_ekf.update(self.amcl.estimate)
        est = self.map_ekf.estimate
        report = self.monitor.check(est, self.agreement.measure(as_array(est.pose)[None], points, sensor))
        self.last_report = report
        if report.evidence >= p.monitor.min_confidence:
            self._last_good = (est.pose, odom)
        if report.lost:
            self._event(now, "lost", report.reason)
            self._relocalize(now, odom, points, sensor)

    def _relocalize(self, now: float, odom: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> None:
        p = self.params
        if self._last_good is not None and points.size:
            good_pose, good_odom = self._last_good
            guess = as_pose(compose(as_array(good_pose), relative(as_array(good_odom), as_array(odom))))
            match = self.matcher.match(points, guess, window_xy_m=p.relocalize_window_m,
                                       window_yaw_rad=p.relocalize_window_rad)
            value = self._fit(match.pose, points, sensor)
            if value >= p.monitor.min_confidence:
                self._track_from(now, match.pose, odom, value)
                self._event(now, "relocalized", f"scan-to-map match near the last good pose at {_where(match.pose)}, "
                                                f"{value:.0%} of the scan on the map")
                return
        self.start_global(now, "the scan does not match the map near the last good pose")
        self._search(now, odom, points, sensor)

    # -- internals ---------------------------------------------------------------------------------
    def _fit(self, pose: Pose2D, points: FloatArray, sensor: tuple[float, float]) -> float:
        """The monitor's evidence for ``pose`` on this scan (unmapped obstacles allowed for)."""
        counts = self.agreement.measure(as_array(pose)[None], points, sensor)
        return robust_agreement(counts, self.params.monitor.unmapped_allowance)

    def _enter(self, phase: Phase, confidence: float) -> None:
        self.phase = phase
        self._search_confidence = confidence
        if phase is not Phase.AMBIGUOUS:
            self._hypotheses = None

    def _track_from(self, now: float, pose: Pose2D, odom: Pose2D, confidence: float) -> None:
        """Tracking starts at a checked ``pose`` (odometry ``odom``), with the confidence it was found with."""
        self._look_around = False  # the operator's request is answered: a later search is the robot's own
        cov = self._matched_covariance()
        self.amcl.initialize(pose, cov, now=now, odom=odom)
        self.map_ekf.reset(PoseEstimate(now, pose, cov), odom)
        self.monitor.reset(confidence, now)
        self._last_good = (pose, odom)
        self._enter(Phase.TRACKING, 0.0)

    def _matched_covariance(self) -> FloatArray:
        p = self.params
        return np.diag([p.matched_std_m**2, p.matched_std_m**2, p.matched_std_rad**2])

    def _event(self, now: float, kind: EventKind, detail: str) -> None:
        self.events.append(LocalizationEvent(now, kind, detail))


def _where(pose: Pose2D) -> str:
    return f"({pose.x_m:.2f}, {pose.y_m:.2f}, {math.degrees(pose.yaw_rad):.0f}°)"


__all__ = ["EventKind", "LocalizationEvent", "Localizer", "LocalizerParams", "Phase"]
