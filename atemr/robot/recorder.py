"""`RunRecorder`: what the robot senses, estimates and decides, as messages for the recording and the live view.

It takes its data from the robot's typed parts, the same on the simulated and the real robot: every scan and
IMU sample (the devices' subscriptions), every wheel sample as localization receives it (`on_wheels`), the
fused odometry, the localized pose and the transforms (10 and 20 Hz), the active map when it changes, the
navigator's global path, camera frames as JPEG at ``camera_hz``, every CAN frame (a bus of its own on the
robot's channel, as `atemr.io.can.recording.BusRecorder` listens), the health board once a second, the
robot's events, the agent's state and its recorder's records (`atemr.fsm.recording.AgentRecorder`), and in
simulation the true pose.

Each message is encoded once (`atemr.io.recording.codec`) and handed to every sink that wants its topic: the
MCAP writer (`atemr.io.recording.mcap_writer.RecordingWriter`, every topic) and the live Foxglove server
(`atemr.ui.foxglove`, the topics a client subscribed to, so nothing is encoded for nobody). Neither sink
blocks. A map can be large (millions of cells, seconds to encode): on a paced robot it is encoded by a
worker thread and handed over when ready; a headless run encodes it at once, so its file is repeatable.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

import can
import numpy as np
from numpy.typing import NDArray

from atemr.clock import due
from atemr.domain.maps import OccupancyMap
from atemr.fsm.agent import Agent
from atemr.fsm.recording import AgentRecorder, Record
from atemr.io.devices.drivers import Devices
from atemr.io.recording import ros2_convert as ros
from atemr.io.recording import topics as tp
from atemr.io.recording.agent_trace import record_entry
from atemr.io.recording.codec import Codec
from atemr.io.recording.mcap_writer import Entry
from atemr.io.sim.simulation import Simulation
from atemr.msgs import ZERO_TWIST, CameraMount, DepthImage, ImuSample, LaserScan, Pose2D, Twist, WheelSpeeds
from atemr.robot.health import HealthBoard
from atemr.robot.mapping import MapService
from atemr.robot.navigation import RobotNavigation
from atemr.skills.localization.pipeline import LocalizationPipeline

F = TypeVar("F")
log = logging.getLogger(__name__)

#: The recorder's tick rate (the transforms'); odometry, poses and the plan go at half of it.
RATE_HZ = 20.0
HEALTH_PERIOD_S = 1.0
#: CAN frames taken from the tap per tick at most (a flooded bus cannot stall the tick).
MAX_CAN_FRAMES = 2000


class MessageSink(Protocol):
    """Where messages go: the MCAP writer, the live server. A sink whose ``encodes`` is true takes them as built
    (`write_message`: a writer process encodes them), the others as bytes (`write`)."""

    encodes: bool

    def wants(self, topic: str) -> bool:
        """Whether a message on ``topic`` would be used now (encoding is skipped when no sink wants it)."""
        ...

    def write(self, topic: str, log_time: int, data: bytes) -> None:
        """Take one encoded message; must not block."""
        ...

    def write_message(self, topic: str, log_time: int, message: Any) -> None:
        """Take one message as built (``encodes`` sinks); must not block."""
        ...


@dataclass(frozen=True)
class RecorderSources:
    """The parts a recorder reads (`atemr.robot.parts.RobotParts` has them all)."""

    devices: Devices
    localization: LocalizationPipeline
    maps: MapService
    navigation: RobotNavigation
    agent: Agent
    health: HealthBoard
    sim: Simulation | None = None
    #: A bus on the robot's CAN channel that only listens (None: CAN frames are not recorded).
    can_tap: can.BusABC | None = None
    jpeg: Callable[[NDArray[np.uint8]], bytes] | None = None
    #: The colour and the depth camera's newest frame, read when the recording's next one is due (None: not
    #: recorded); a simulated camera renders it then unless a consumer keeps it rendering.
    camera_frame: Callable[[], NDArray[np.uint8] | None] | None = None
    depth_frame: Callable[[], DepthImage | None] | None = None


class RunRecorder:
    """See the module docstring. ``threaded_maps``: encode maps on a worker thread (a paced robot)."""

    name = "recorder"

    def __init__(self, sources: RecorderSources, sinks: Iterable[MessageSink], *, camera_hz: float = 1.0,
                 depth_hz: float = 1.0, pose_hz: float = 2.0, meta: dict[str, Any] | None = None,
                 threaded_maps: bool = False) -> None:
        self.sources = sources
        self.sinks = list(sinks)
        self.codec = Codec()
        self._camera_frames: FrameSampler[Any] = FrameSampler(camera_hz)
        self._depth_frames: FrameSampler[DepthImage] = FrameSampler(depth_hz)
        self.agent_recorder = AgentRecorder(sources.agent, self._on_record, pose_hz=pose_hz, meta=meta)
        self.messages = 0
        self._ticks = 0
        self._next_health = float("-inf")
        self._depth_mount: CameraMount | None = None  # the depth camera's, once a frame said where it is
        self._map: OccupancyMap | None = None
        self._map_bytes: Entry | None = None
        self._static: Entry | None = None
        self._laser: Pose2D | None = None
        self._path: object = None
        self._plan: Entry | None = None
        self._state: tuple[str, str | None] | None = None
        self._session: tuple[bool, bool] | None = None
        self._pending_events: deque[tuple[float, str, str]] = deque(maxlen=1000)
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="atemr-recorder") if threaded_maps else None
        self._attached = False

    # -- life cycle ---------------------------------------------------------------------------------------------
    def attach(self) -> RunRecorder:
        """Subscribe to the devices and the agent (idempotent)."""
        if not self._attached:
            self._attached = True
            self.sources.devices.lidar.subscribe(self.on_scan)
            self.sources.devices.imu.subscribe(self.on_imu)
            self.agent_recorder.attach()
        return self

    def shutdown(self) -> None:
        """Stop the map worker and close the CAN tap (idempotent)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
        if self.sources.can_tap is not None:
            self.sources.can_tap.shutdown()

    # -- emitting -----------------------------------------------------------------------------------------------
    def _emit(self, topic: str, t: float, build: Callable[[], Any], *, keep: bool = False) -> Entry | None:
        """Build the message for ``topic`` at robot time ``t`` if a sink wants it and hand it to each: encoded
        once for the sinks that take bytes, as built for a writer process. ``keep``: encode it here in any case
        and return it (what a part's preamble repeats)."""
        wanting = [s for s in self.sinks if s.wants(topic)]
        if not wanting and not keep:
            return None
        message = build()
        log_time = ros.nanoseconds(t)
        entry = (topic, log_time, self.codec.encode(topic, message)) if keep else None
        for sink in wanting:
            if sink.encodes:
                sink.write_message(topic, log_time, entry[2] if entry is not None else message)
                continue
            if entry is None:
                entry = (topic, log_time, self.codec.encode(topic, message))
            sink.write(*entry)
        self.messages += 1
        return entry

    def _wanted(self, topic: str) -> bool:
        return any(s.wants(topic) for s in self.sinks)

    def _emit_message(self, topic: str, t: float, message: Any) -> Entry | None:
        """`_emit` for a message already built (cheap ones)."""
        return self._emit(topic, t, lambda: message)

    def _send(self, entry: Entry, sinks: list[MessageSink] | None = None) -> None:
        for sink in sinks if sinks is not None else self.sinks:
            if sinks is not None or sink.wants(entry[0]):
                sink.write(*entry)
        self.messages += 1

    def _on_record(self, record: Record) -> None:
        self._send(record_entry(record))

    def preamble(self) -> list[Entry]:
        """What opens every recording part: the agent's state, the static transforms, the map, the plan."""
        out = [record_entry(r) for r in self.agent_recorder.preamble()]
        agent = self.sources.agent
        out.append((tp.AGENT_STATE.name, ros.nanoseconds(agent.context.now),
                    self.codec.encode(tp.AGENT_STATE.name, {"t": agent.context.now, "state": agent.state,
                                                           "mode": agent.context.mode})))
        out += [e for e in (self._static, self._map_bytes, self._plan) if e is not None]
        return out

    # -- subscriptions ------------------------------------------------------------------------------------------
    def on_scan(self, scan: LaserScan) -> None:
        if scan.sensor_pose != self._laser:
            self._laser = scan.sensor_pose
            self._static_transforms(scan.t)
        self._emit(tp.SCAN.name, scan.t, lambda: ros.scan_msg(scan))

    def _static_transforms(self, t: float) -> None:
        """Every part's place on the base (kept: each file part starts with it); sent again when a part's
        place becomes known or changes (the depth camera's, with its first frame)."""
        laser = self._laser or Pose2D()
        parts = [ros.transform(t, ros.BASE_FRAME, ros.LASER_FRAME, laser),
                 ros.transform(t, ros.BASE_FRAME, ros.IMU_FRAME, Pose2D()),
                 ros.transform(t, ros.BASE_FRAME, ros.CAMERA_FRAME, Pose2D())]
        if self._depth_mount is not None:
            parts.append(ros.optical_transform(t, ros.BASE_FRAME, self._depth_mount))
        self._static = self._emit(tp.TF_STATIC.name, t, keep=True, build=lambda: ros.tf_msg(parts))

    def on_imu(self, sample: ImuSample) -> None:
        self._emit(tp.IMU.name, sample.t, lambda: ros.imu_msg(sample))

    def on_wheels(self, now: float, wheels: WheelSpeeds) -> None:
        """A wheel sample as localization received it (the robot's wheel-odometry ticker calls this)."""
        self._emit(tp.WHEEL_ODOM.name, now,
                   lambda: ros.twist_msg(now, self.sources.localization.drive.measured(wheels)))

    # -- the tick -----------------------------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        self._ticks += 1
        self._can(now)
        self._transforms(now)
        if self._ticks % 2 == 1:
            self._poses(now)
            self._plan_changed(now)
        self._map_changed(now)
        self._mapping(now)
        self._agent_state(now)
        self._events()
        if due(now, self._next_health):
            self._next_health = now + HEALTH_PERIOD_S
            self._emit(tp.HEALTH.name, now, lambda: {"t": now, "components": {
                name: {"ok": h.ok, "reason": h.detail} for name, h in self.sources.health.collect().items()}})
            odometry = self.sources.localization.odometry
            self._emit(tp.GYRO_BIAS.name, now, lambda: {"t": now, "bias_radps": odometry.gyro_bias_radps,
                                                        "standing": odometry.standing})
        self._camera(now)
        self._depth(now)

    def _can(self, now: float) -> None:
        """The frames the tap heard since the last tick, as one message (hundreds a second: one each would cost
        the robot's thread more than all the sensors)."""
        tap = self.sources.can_tap
        if tap is None:
            return
        frames = []
        for _ in range(MAX_CAN_FRAMES):
            msg = tap.recv(timeout=0)
            if msg is None:
                break
            if not msg.is_error_frame:
                frames.append(msg)
        if frames and self._wanted(tp.CAN.name):
            self._emit_message(tp.CAN.name, now, {"t": now, "frames": [_frame(m) for m in frames]})

    def _transforms(self, now: float) -> None:
        loc = self.sources.localization
        odom = loc.odom_pose
        moves = [ros.transform(now, ros.ODOM_FRAME, ros.BASE_FRAME, odom)]
        correction = loc.localizer.map_to_odom() if loc.localized and loc.localizer is not None else None
        if correction is not None:
            moves.append(ros.transform(now, ros.MAP_FRAME, ros.ODOM_FRAME, correction))
        self._emit(tp.TF.name, now, lambda: ros.tf_msg(moves))

    def _poses(self, now: float) -> None:
        loc = self.sources.localization
        est = loc.odometry.estimate
        state = loc.odometry.state  # [x, y, yaw, v, w]
        twist = Twist(float(state[3]), float(state[4]))
        self._emit(tp.ODOM.name, now, lambda: ros.odometry_msg(now, est.pose, twist, pose_cov=est.covariance))
        pose, estimate = loc.map_pose(), loc.estimate
        if pose is not None:
            cov = estimate.covariance if estimate is not None else None
            self._emit(tp.POSE.name, now, lambda: ros.pose_cov_msg(now, pose, cov))
        sim = self.sources.sim
        if sim is not None:
            truth = sim.pose
            self._emit(tp.GROUND_TRUTH.name, now,
                       lambda: ros.odometry_msg(now, truth, ZERO_TWIST, frame=ros.MAP_FRAME))

    def _plan_changed(self, now: float) -> None:
        status = self.sources.navigation.last_status
        path = status.global_path if status is not None and status.state == "RUNNING" else None
        if path is self._path:
            return
        self._path = path
        points = path if path is not None else np.zeros((0, 2))
        self._plan = self._emit(tp.PLAN.name, now, lambda: ros.path_msg(now, points), keep=True)

    def _map_changed(self, now: float) -> None:
        grid = self.sources.maps.active
        if grid is None or grid is self._map:
            return
        self._map = grid
        if self._pool is None:
            self._map_bytes = self._emit(tp.MAP.name, now, lambda: ros.grid_msg(now, grid), keep=True)
            return
        self._pool.submit(self._encode_map, now, grid)

    def _encode_map(self, now: float, grid: OccupancyMap) -> None:
        """On the worker: encode the map, then hand it over (the writer and the live server take any thread)."""
        try:
            entry = (tp.MAP.name, ros.nanoseconds(now), self.codec.encode(tp.MAP.name, ros.grid_msg(now, grid)))
        except Exception:
            log.exception("recording: the map %s could not be encoded", grid.name)
            return
        if grid is self._map:
            self._map_bytes = entry
            self._send(entry)

    def _mapping(self, now: float) -> None:
        maps = self.sources.maps
        session = (maps.slam is not None, maps.slam is not None and maps.collecting)
        if session != self._session:
            self._session = session
            self._emit_message(tp.MAPPING.name, now, {"t": now, "active": session[0], "collecting": session[1]})

    def _agent_state(self, now: float) -> None:
        agent = self.sources.agent
        state = (agent.state, agent.context.mode)
        if state != self._state:
            self._state = state
            self._emit(tp.AGENT_STATE.name, now, lambda: {"t": now, "state": state[0], "mode": state[1]})

    def on_event(self, t: float, kind: str, text: str) -> None:
        """A robot event (`atemr.robot.core.Robot.event`, any thread): recorded at the next tick."""
        self._pending_events.append((t, kind, text))

    def _events(self) -> None:
        while self._pending_events:
            t, kind, text = self._pending_events.popleft()
            self._emit_message(tp.EVENTS.name, t, {"t": t, "kind": kind, "text": text})

    def _camera(self, now: float) -> None:
        jpeg = self.sources.jpeg
        if jpeg is None:
            return
        frame = self._camera_frames.take(self.sources.camera_frame, now)
        if frame is None:
            return
        self._emit(tp.CAMERA.name, now, lambda: ros.image_msg(now, jpeg(frame)))

    def _depth(self, now: float) -> None:
        frame = self._depth_frames.take(self.sources.depth_frame, now)
        if frame is None:
            return
        if frame.mount != self._depth_mount:
            self._depth_mount = frame.mount
            self._static_transforms(frame.t)
        self._emit(tp.DEPTH_INFO.name, frame.t, lambda: ros.depth_info_msg(frame))
        self._emit(tp.DEPTH.name, frame.t, lambda: ros.depth_image_msg(frame))


class FrameSampler(Generic[F]):
    """A camera's newest frame at most ``rate_hz`` times a second of robot time, never the same frame twice
    (``rate_hz`` 0: none at all). ``next_t`` is when the next one is due, -inf before the first."""

    def __init__(self, rate_hz: float) -> None:
        self.period_s = 1.0 / rate_hz if rate_hz > 0 else float("inf")
        self.next_t = float("-inf") if rate_hz > 0 else float("inf")
        self._last: object = None

    def take(self, read: Callable[[], F | None] | None, now: float) -> F | None:
        """The newest frame (``read()``, called only when one is due) if it is new, else None."""
        if read is None or not due(now, self.next_t):
            return None
        frame = read()
        if frame is None or frame is self._last:
            return None
        self.next_t = now + self.period_s
        self._last = frame
        return frame


def _frame(msg: can.Message) -> dict[str, Any]:
    return {"id": msg.arbitration_id, "data": bytes(msg.data).hex(), "extended": msg.is_extended_id,
            "remote": msg.is_remote_frame}


__all__ = ["RATE_HZ", "MessageSink", "RecorderSources", "RunRecorder"]
