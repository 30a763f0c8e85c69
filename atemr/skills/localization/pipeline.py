"""The whole localization stack as one scheduler component: ``odom`` from the odometry EKF, ``map`` from AMCL.

Inputs arrive through callbacks (cheap, any order the sources produce them): wheel speeds
(`on_wheels`, from the motor driver's feedback), IMU samples (`on_imu`) and scans (`on_scan`, kept
until the next tick). Each tick handles the newest scan:

1. ICP of the scan against the previous one, starting from the odometry EKF's own increment, gives
   the scan-matcher measurement of the twist (`OdometryEkf.update_scan_match`), unless odometry says the
   robot stood still since the previous scan (every wheel measurement in between was zero, or a step of the
   motors' speed readings from it: `OdometryEkf.stands_still`): a match would only confirm it, and a robot
   waiting for its next command is most of a day. The previous scan's target
   (its k-d tree and its normals, from neighbouring beams) is built only when a match needs it;
2. the `Localizer` gets the scan with the ``odom`` pose of its time (AMCL, map EKF, covariance monitor,
   relocalization).

Tick it at the lidar rate (10 Hz). Outputs: `odom_pose`, `estimate` (map pose + covariance, None while
not localized), `confidence` and `localized` (confidence at or above the limit), `status` (the confidence, its
limit and the state, as 0x153 bit 4, the dashboard and the agent's guards read them), `candidates` (while
global localization is ambiguous), `map_to_odom`, and `drain_events` for the agent and the dashboard.
Selecting another map drops the pose (an event says so). No I/O and no clock of its own: every time comes
from the inputs or the scheduler's ``now``.
"""

from __future__ import annotations

import bisect
import math
from collections import deque

import numpy as np

from atemr.domain.maps import OccupancyMap
from atemr.domain.status import LocalizationState, LocalizationStatus
from atemr.errors import NavigationError, ProtocolError
from atemr.msgs import ImuSample, LaserScan, Pose2D, Twist, WheelSpeeds
from atemr.skills.diff_drive import DiffDrive
from atemr.skills.localization.amcl import PoseEstimate
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, compose, relative
from atemr.skills.localization.global_search import Hypothesis
from atemr.skills.localization.icp import IcpTarget, icp
from atemr.skills.localization.localizer import LocalizationEvent, Localizer, LocalizerParams
from atemr.skills.localization.odometry_ekf import OdometryEkf, OdometryEkfParams
from atemr.skills.localization.scan import scan_points

#: Odometry poses kept to look up the pose at a scan's time (2 s at 50 Hz).
_HISTORY = 100


class _PreviousScan:
    """The last scan handled, its points and the ``odom`` pose of its time; its ICP target built when first asked
    (never, while the robot stands still)."""

    def __init__(self, scan: LaserScan, points: FloatArray, odom: Pose2D) -> None:
        self.scan = scan
        self.points = points
        self.odom = odom
        self._target: IcpTarget | None = None

    def target(self) -> IcpTarget:
        if self._target is None:
            self._target = IcpTarget.from_scan(self.points)
        return self._target


class LocalizationPipeline:
    """See the module docstring. ``grid`` is the active map (None: odometry only until `set_map`)."""

    name = "localization"

    def __init__(
        self,
        grid: OccupancyMap | None,
        rng: np.random.Generator,
        *,
        drive: DiffDrive | None = None,
        odometry: OdometryEkfParams | None = None,
        localizer: LocalizerParams | None = None,
    ) -> None:
        self.drive = drive or DiffDrive()
        self.rng = rng
        self.localizer_params = localizer or LocalizerParams()
        self.odometry = OdometryEkf(odometry)
        self.localizer: Localizer | None = None
        self._times: deque[float] = deque(maxlen=_HISTORY)
        self._poses: deque[Pose2D] = deque(maxlen=_HISTORY)
        self._pending: LaserScan | None = None
        self._prev: _PreviousScan | None = None
        self._events: list[LocalizationEvent] = []
        self.scans_used = 0
        self.icp_failures = 0
        #: Scans not matched to the one before because odometry said the robot stood still.
        self.icp_skipped = 0
        #: Wheel measurements since the last scan handled, and whether any of them moved.
        self._wheel_samples = 0
        self._wheels_moved = False
        if grid is not None:
            self.set_map(grid)

    # -- control -----------------------------------------------------------------------------------
    def prepare_map(self, grid: OccupancyMap) -> Localizer:
        """The localizer of ``grid`` (likelihood field, scan-to-map matcher: the heavy part of a map change),
        built without touching this pipeline, so any thread may call it; hand it to `set_map`. Raises
        `ConfigError` when the map cannot be localized against (no occupied or no free cell)."""
        return Localizer(grid, self.rng, self.localizer_params)  # the rng is only kept here, drawn from later

    def set_map(self, grid: OccupancyMap, prepared: Localizer | None = None, *, pose_follows: bool = False) -> None:
        """Localize against ``grid`` from now on (the operator selected another map): pose unknown again.

        ``prepared``: ``prepare_map(grid)``, built beforehand; the change is then only a swap. ``pose_follows``: the
        caller sets the pose on it at once (the map just made by SLAM, where the robot's pose is known), so the
        change is not announced as "not localized": the carer read that beside "The robot knows where it is"."""
        if prepared is not None and prepared.map is not grid:
            raise ValueError("set_map: the prepared localizer belongs to another map")
        localizer = prepared if prepared is not None else self.prepare_map(grid)
        if self.localizer is not None:
            self._events.extend(self.localizer.events)
            if not pose_follows:
                self.announce_not_localized(grid.name)
        self.localizer = localizer

    def announce_not_localized(self, map_name: str, why: str = "") -> None:
        """Tell the operator the robot does not know where it is on ``map_name``: after a map change, or when the
        pose `set_map`'s ``pose_follows`` promised could not be set (``why``)."""
        self._events.append(LocalizationEvent(self.odometry.t, "map_changed",
                                              f"map {map_name} selected{f' ({why})' if why else ''}: not localized "
                                              "until a pose is set or found (FIND POSITION)"))

    def _need(self) -> Localizer:
        if self.localizer is None:
            raise NavigationError("no active map: select or build a map before localizing")
        return self.localizer

    def set_initial_pose(self, now: float, pose: Pose2D, covariance: np.ndarray | None = None) -> None:
        """The operator's pose on the map (`NavigationError` if it is not in free space)."""
        self._need().set_initial_pose(now, pose, covariance, odom=self.odometry.pose)

    def start_global(self, now: float, why: str = "requested", *, look_around: bool = False) -> None:
        """Global localization (the pose is unknown); ``why`` goes into the event; ``look_around``: the operator
        asked, so an ambiguous answer may turn the robot in place (`Localizer.start_global`)."""
        self._need().start_global(now, why, look_around=look_around)

    # -- inputs ------------------------------------------------------------------------------------
    def _remember(self) -> None:
        self._times.append(self.odometry.t)
        self._poses.append(self.odometry.pose)

    def on_wheels(self, now: float, wheels: WheelSpeeds) -> None:
        """Measured wheel speeds at ``now``."""
        self.on_wheel_twist(now, self.drive.measured(wheels))

    def on_wheel_twist(self, now: float, twist: Twist) -> None:
        """The base twist the wheels measured at ``now`` (a recording keeps this: `atemr.robot.replay`)."""
        self._wheel_samples += 1
        self._wheels_moved |= not self.odometry.stands_still(twist)
        if self.odometry.update_wheels(now, twist):
            self._remember()

    def on_imu(self, sample: ImuSample) -> None:
        if self.odometry.update_imu(sample):
            self._remember()

    def on_scan(self, scan: LaserScan) -> None:
        """Keep the newest scan for the next tick (an older unhandled one is superseded).

        A scan whose ranges are not one-dimensional is refused (`ProtocolError`), as the motion pipeline
        refuses it, and the pending scan is kept.
        """
        shape = np.shape(scan.ranges_m)
        if len(shape) != 1:
            raise ProtocolError(f"scan at t={scan.t}: ranges_m must be one-dimensional, got shape {shape}")
        self._pending = scan

    # -- tick --------------------------------------------------------------------------------------
    def odom_at(self, t: float) -> Pose2D:
        """The ``odom`` pose at time ``t`` (the latest one recorded at or before it)."""
        if not self._times:
            return self.odometry.pose
        i = bisect.bisect_right(self._times, t) - 1
        return self._poses[max(i, 0)]

    def tick(self, now: float) -> None:
        scan, self._pending = self._pending, None
        if scan is None or not math.isfinite(scan.t):
            return
        odom = self.odom_at(scan.t)
        points = scan_points(scan)
        prev = self._prev
        if prev is not None and points.shape[0] >= 20 and scan.t > prev.scan.t:
            if self._wheel_samples and not self._wheels_moved:
                self.icp_skipped += 1
            else:
                dt = scan.t - prev.scan.t
                guess = relative(as_array(prev.odom), as_array(odom))
                match = icp(points, prev.target(), as_pose(guess))
                if match.ok and match.inlier_fraction > 0.5:
                    self.odometry.update_scan_match(max(scan.t, self.odometry.t), match.pose, dt, match.covariance)
                    self._remember()
                else:
                    self.icp_failures += 1
        self._prev = _PreviousScan(scan, points, odom)
        self._wheel_samples, self._wheels_moved = 0, False
        if self.localizer is not None:
            self.localizer.update(scan.t, odom, scan, points=points)
        self.scans_used += 1

    # -- outputs -----------------------------------------------------------------------------------
    @property
    def odom_pose(self) -> Pose2D:
        return self.odometry.pose

    @property
    def localized(self) -> bool:
        """Whether the confidence is at or above the limit (`Localizer.localized`); False without a map."""
        return self.localizer is not None and self.localizer.localized

    @property
    def confidence(self) -> float:
        """The one confidence number (`Localizer.confidence`); 0 without a map."""
        return 0.0 if self.localizer is None else self.localizer.confidence

    @property
    def min_confidence(self) -> float:
        """The localization limit the confidence is compared with."""
        return self.localizer_params.monitor.min_confidence

    @property
    def state(self) -> LocalizationState:
        """``no map``, or the localizer's state (localized, lost, searching, ambiguous, failed, ...)."""
        return "no map" if self.localizer is None else self.localizer.state

    @property
    def status(self) -> LocalizationStatus:
        """The one confidence number (rounded as every consumer shows it), its limit and the state: what the
        agent's guards, 0x153 bit 4, the dashboard and the command line all read."""
        return LocalizationStatus(round(self.confidence, 4), self.min_confidence, self.state)

    def stop_looking(self) -> None:
        """The operator took over: no more turning by itself for this search (`Localizer.stop_looking`)."""
        if self.localizer is not None:
            self.localizer.stop_looking()

    @property
    def wants_a_look(self) -> bool:
        """Whether the operator's global search is ambiguous and the robot should turn to see more
        (`Localizer.wants_a_look`); False without a map."""
        return self.localizer is not None and self.localizer.wants_a_look

    @property
    def candidates(self) -> tuple[Hypothesis, ...]:
        """The places global localization could not tell apart (while ambiguous), best first."""
        return () if self.localizer is None else self.localizer.candidates

    @property
    def estimate(self) -> PoseEstimate | None:
        """Map pose at the last scan, or None while not localized."""
        return None if self.localizer is None else self.localizer.estimate

    def map_pose(self) -> Pose2D | None:
        """The current map pose: the map→odom correction composed with the newest odometry."""
        if self.localizer is None or not self.localizer.localized:
            return None
        corr = self.localizer.map_to_odom()
        if corr is None:
            return None
        return as_pose(compose(as_array(corr), as_array(self.odom_pose)))

    def drain_events(self) -> list[LocalizationEvent]:
        """Events since the last call (lost, relocalized, localized, ...), oldest first."""
        out = self._events
        if self.localizer is not None:
            out = out + self.localizer.events
            self.localizer.events = []
        self._events = []
        return out


__all__ = ["LocalizationPipeline"]
