"""A recording fed back into the algorithms: SLAM rebuilt from its scans, odometry and IMU, or localization re-run.

This is how SLAM and AMCL are tuned on real data: record a run (every run records), change a parameter, replay.
The recording's messages are taken in file order, which is the order the robot's parts received them, and
each goes where it went on the robot:

* ``/wheel_odom`` (the twist localization received), ``/imu`` and ``/scan`` into a fresh
  `LocalizationPipeline` (the odometry EKF with its scan matching; with ``--localize`` also AMCL on the map);
* ``/scan`` into the SLAM session with the fused odometry of its time, as `atemr.robot.mapping.MapService`
  does, while the recording says a mapping session collected (``/mapping``); its start pose and anchor map
  are the recorded localized pose (``/pose``) and active map (``/map``) of that moment, as they were live;
* the pipeline is ticked at each scan's time once every message of that time is in, as the scheduler ticks it
  after the devices and the wheel feed.

``/tf_static`` gives where the lidar sits on the base. The reference poses (``/pose``, and ``/sim/ground_truth``
when the run was simulated) are what ``--localize`` compares against. Pure apart from reading the file.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError
from atemr.io.recording import ros2_convert as ros
from atemr.io.recording import topics as tp
from atemr.io.recording.mcap_reader import Recorded, RecordingReader
from atemr.msgs import Pose2D
from atemr.skills.localization.localizer import LocalizerParams
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.slam import OccupancyGridSlam, SlamParams

#: Called with the share of the file read so far (0..1) and the robot time reached.
Progress = Callable[[float, float], None]

TOPICS = {tp.SCAN.name, tp.IMU.name, tp.WHEEL_ODOM.name, tp.TF_STATIC.name, tp.MAP.name, tp.POSE.name,
          tp.MAPPING.name, tp.GROUND_TRUTH.name}


@dataclass
class PoseErrors:
    """Position and heading errors of the replayed pose against a reference, sampled at each scan."""

    position_m: list[float] = field(default_factory=list)
    heading_rad: list[float] = field(default_factory=list)

    def add(self, pose: Pose2D, reference: Pose2D) -> None:
        self.position_m.append(math.hypot(pose.x_m - reference.x_m, pose.y_m - reference.y_m))
        d = pose.yaw_rad - reference.yaw_rad
        self.heading_rad.append(abs(math.atan2(math.sin(d), math.cos(d))))

    def report(self) -> dict[str, Any]:
        if not self.position_m:
            return {"samples": 0, "rmse_m": None, "max_m": None, "rmse_yaw_rad": None}
        pos, yaw = np.array(self.position_m), np.array(self.heading_rad)
        return {"samples": len(pos), "rmse_m": float(np.sqrt(np.mean(pos ** 2))), "max_m": float(pos.max()),
                "rmse_yaw_rad": float(np.sqrt(np.mean(yaw ** 2)))}


@dataclass
class ReplayResult:
    """What a replay did: the messages fed, the span of robot time, the SLAM map, the pose errors, the warnings."""

    file: Path
    messages: int = 0
    scans: int = 0
    start_t: float | None = None
    end_t: float | None = None
    grid: OccupancyMap | None = None
    slam_updates: int = 0
    sessions: int = 0
    localized_scans: int = 0
    against_recorded: PoseErrors = field(default_factory=PoseErrors)
    against_truth: PoseErrors = field(default_factory=PoseErrors)
    warnings: list[str] = field(default_factory=list)


class Replay:
    """Feeds one recording into a localization pipeline and, when ``slam`` is given, a SLAM session."""

    def __init__(self, path: str | Path, *, slam: SlamParams | None = None, grid: OccupancyMap | None = None,
                 localizer: LocalizerParams | None = None, seed: int = 0, all_scans: bool = False,
                 progress: Progress | None = None, pace: Callable[[float], None] | None = None) -> None:
        self.reader = RecordingReader(path)
        self.slam_params = slam
        self.pipeline = LocalizationPipeline(grid, np.random.default_rng(seed), localizer=localizer)
        self.localize = grid is not None
        self.progress = progress
        self.pace = pace
        self.result = ReplayResult(self.reader.path)
        self.slam: OccupancyGridSlam | None = None
        self._collecting = False
        self.all_scans = all_scans and slam is not None
        self._laser = Pose2D()
        self._map: OccupancyMap | None = None
        self._recorded_pose: Pose2D | None = None
        self._truth: Pose2D | None = None
        self._pending_t: float | None = None
        self._initialized = False

    def run(self) -> ReplayResult:
        """Replay the whole file (up to any damage: its warning is in the result)."""
        handlers = {tp.SCAN.name: self._scan, tp.IMU.name: self._imu, tp.WHEEL_ODOM.name: self._wheels,
                    tp.TF_STATIC.name: self._static, tp.MAP.name: self._grid, tp.POSE.name: self._pose,
                    tp.MAPPING.name: self._mapping, tp.GROUND_TRUTH.name: self._ground_truth}
        for message in self.reader.messages(TOPICS):
            t = message.log_time / 1e9
            if self._pending_t is not None and t > self._pending_t:
                self._tick()
            if self.result.start_t is None:
                self.result.start_t = t
            self.result.end_t = t
            handlers[message.topic](t, self.reader.decode(message))
            self.result.messages += 1
            self._report(t, message)
        if self._pending_t is not None:
            self._tick()
        self.result.warnings = list(self.reader.warnings)
        if self.slam is not None:
            self.result.grid = self.slam.to_map("replay")
            self.result.slam_updates = self.slam.updates
        return self.result

    def _report(self, t: float, message: Recorded) -> None:
        if self.pace is not None and message.topic == tp.SCAN.name:
            self.pace(t)
        if self.progress is not None and message.topic == tp.SCAN.name:
            self.progress(self.reader.good_bytes / max(self.reader.size_bytes, 1), t)

    # -- the messages ------------------------------------------------------------------------------------
    def _static(self, t: float, msg: Any) -> None:
        laser = ros.transforms_from(msg).get((ros.BASE_FRAME, ros.LASER_FRAME))
        if laser is not None:
            self._laser = laser

    def _grid(self, t: float, msg: Any) -> None:
        self._map = ros.grid_from(msg, "recorded")

    def _pose(self, t: float, msg: Any) -> None:
        self._recorded_pose = ros.pose_from(msg.pose.pose)
        if self.localize and not self._initialized:  # the operator's initial pose, as the robot had it
            self._initialized = True
            self.pipeline.set_initial_pose(t, self._recorded_pose)

    def _ground_truth(self, t: float, msg: Any) -> None:
        self._truth = ros.pose_from(msg.pose.pose)

    def _wheels(self, t: float, msg: Any) -> None:
        self.pipeline.on_wheel_twist(t, ros.twist_from(msg))

    def _imu(self, t: float, msg: Any) -> None:
        self.pipeline.on_imu(ros.imu_from(msg))

    def _mapping(self, t: float, msg: Any) -> None:
        if self.slam_params is None or (self.all_scans and self.slam is not None):
            return
        if msg["active"] and self.slam is None:
            anchor = self._map if self._recorded_pose is not None else None
            self.slam = OccupancyGridSlam(self.slam_params, start=self._recorded_pose or Pose2D(), anchor=anchor)
            self.result.sessions += 1
        self._collecting = bool(msg["collecting"]) and self.slam is not None

    def _scan(self, t: float, msg: Any) -> None:
        scan = ros.scan_from(msg, self._laser)
        if self.all_scans and self.slam is None:
            self._mapping(t, {"active": True, "collecting": True})
        if self.slam is not None and self._collecting:
            self.slam.update(self.pipeline.odom_at(scan.t), scan)
        self.pipeline.on_scan(scan)
        self._pending_t = t
        self.result.scans += 1

    def _tick(self) -> None:
        assert self._pending_t is not None
        self.pipeline.tick(self._pending_t)
        self._pending_t = None
        if not self.localize:
            return
        pose = self.pipeline.map_pose()
        if pose is None:
            return
        self.result.localized_scans += 1
        if self._recorded_pose is not None:
            self.result.against_recorded.add(pose, self._recorded_pose)
        if self._truth is not None:
            self.result.against_truth.add(pose, self._truth)


def replay_slam(path: str | Path, params: SlamParams, **kwargs: Any) -> ReplayResult:
    """The map a recording's mapping session gives with ``params`` (``all_scans``: every scan of it). A
    `ConfigError` when it holds no scan, or no mapping session and ``all_scans`` is not set."""
    result = Replay(path, slam=params, **kwargs).run()
    if result.scans == 0:
        raise ConfigError("the recording holds no scan (/scan) to map from", file=path)
    if result.grid is None:
        raise ConfigError("the recording holds no mapping session (/mapping): map all of its scans with "
                          "--all-scans", file=path)
    return result


__all__ = ["PoseErrors", "Replay", "ReplayResult", "replay_slam"]
