"""`RobotGatewayImpl`: the dashboard's `atemr.ui.gateway.RobotGateway` over the assembled robot.

Every method may be called from the web server's threads. Nothing here ticks a part or changes the scene
directly: commands go to the agent's inbox (`Agent.submit`, after `Agent.precheck` so a command that
cannot be taken is refused at once with the reason), the joystick onto `MotionInputs`, simulation
interventions through `Simulation.submit`, and the few actions that touch the control thread's objects
(initial pose, map selection, draining localization events, reporting the agent's verdicts) are queued
for the gateway's own scheduler component, ``dashboard_gateway``, which runs them on the robot's thread.
What can be checked at once (a finite pose, a map that exists, limits within bounds) is checked at once.

Nothing heavy runs on the robot's thread on a web request's behalf: the queued actions are cheap, at most
`MAX_ACTIONS_PER_TICK` of them run per tick and at most `MAX_QUEUED_ACTIONS` wait (more are refused). A map
selection reads, decodes and prepares the map (`MapService.prepare`: localization's likelihood field,
navigation's costmap) in the gateway's own worker thread, one map at a time, while the robot goes on;
only the finished map is queued, and the pump swaps it in between two ticks (`MapService.swap`).

Building the gateway schedules two small components on the robot: the pump above and, when the robot
has a camera, the `VideoRecorder` (which only queues raw frames there; its own worker encodes). Build it
before the robot starts (`atemr.robot.dashboard.add_dashboard` does).
"""

from __future__ import annotations

import logging
import math
import queue
import threading
from collections import deque
from collections.abc import Callable, Collection
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from atemr.clock import WallClock
from atemr.domain.routines import RoutineBook
from atemr.errors import AtemrError, ConfigError, brief, brief_text
from atemr.fsm.agent import DEFAULT_AGENT_FILE
from atemr.fsm.machine import TransitionRecord
from atemr.io.devices.drivers import camera_rate_hz, driver_name
from atemr.msgs import Pose2D, Twist
from atemr.robot.core import Robot
from atemr.robot.inputs import CAN_BUS_STOP, HEARTBEAT_STOP
from atemr.robot.mapping import PreparedMap
from atemr.robot.places import PlaceEditor
from atemr.robot.plain_words import (
    plain_goal_refusal,
    plain_guard_refusal,
    plain_outcome,
    plain_refusal,
    plain_unconfirmed,
)
from atemr.robot.port import jpeg
from atemr.robot.video import VideoRecorder
from atemr.skills.nav.navigator import NavStatus
from atemr.skills.ramp import checked_limits
from atemr.trees.missions import GOAL_TASK
from atemr.ui.gateway import CommandResult, MapImage
from atemr.ui.snapshot import (
    navigation_json,
    points_json,
    pose_json,
    render_map,
    scan_points,
    status_levels,
    system_json,
)
from atemr.ui.state import BatteryJson, LocalizationJson, MissionJson, Mode, RobotState, StopCause, top_state

log = logging.getLogger(__name__)

#: How often the gateway's pump runs on the robot's thread.
PUMP_RATE_HZ = 10.0
#: Longest a web request waits for a WiFi join before answering "still joining".
WIFI_WAIT_S = 10.0
#: The secondary core's button: a press is at most this long (5 s powers off; a little margin).
MAX_BUTTON_HOLD_S = 10.0
#: Events shown on the dashboard.
EVENTS_SHOWN = 30
#: Candidate places of an ambiguous global localization drawn on the map at most.
MAX_CANDIDATES_SHOWN = 12
#: Longest a web request waits for a map to be read and prepared before answering "still loading".
MAP_WAIT_S = 30.0
#: Queued actions the pump runs per tick at most (the rest wait for the next tick) ...
MAX_ACTIONS_PER_TICK = 16
#: ... and actions that may wait at most: a flood of requests is refused, not queued without end.
MAX_QUEUED_ACTIONS = 256


def _ok(result: bool, reason: str = "") -> CommandResult:
    return CommandResult.accepted() if result else CommandResult.refused(reason)


def _finite(*values: float) -> bool:
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def _pose_ok(pose: Pose2D, what: str) -> str | None:
    if not isinstance(pose, Pose2D):
        return f"{what} must be a pose, got {type(pose).__name__}"
    if not _finite(pose.x_m, pose.y_m, pose.yaw_rad):
        return f"{what} has a non-finite coordinate: x={pose.x_m}, y={pose.y_m}, yaw={pose.yaw_rad}"
    return None


class _Pump:
    """The gateway's scheduler component: its queued actions run here, on the robot's thread."""

    name = "dashboard_gateway"

    def __init__(self, gateway: RobotGatewayImpl) -> None:
        self.gateway = gateway

    def tick(self, now: float) -> None:
        self.gateway._pump(now)

    def shutdown(self) -> None:
        self.gateway.close()


class RobotGatewayImpl:
    """`atemr.ui.gateway.RobotGateway` over a `Robot` built by `atemr.robot.build_robot` (module docstring)."""

    def __init__(self, robot: Robot, *, pump_rate_hz: float = PUMP_RATE_HZ) -> None:
        self.robot = robot
        self.config = robot.config
        parts = robot.parts
        self.agent = parts.agent
        self.inputs = parts.inputs
        self.health = parts.health
        self.pipeline = parts.pipeline
        self.settings = parts.settings
        self.maps = parts.maps
        self.store = parts.map_store
        self.sim = parts.sim
        self.camera = parts.devices.camera
        self.link = parts.link
        self.missions_dir = (self.config.agent.file or DEFAULT_AGENT_FILE).parent / "missions"
        self._lock = threading.Lock()
        self._actions: queue.SimpleQueue[tuple[str, Callable[[float], object]]] = queue.SimpleQueue()
        self._watched: deque[tuple[int, str]] = deque()
        self.agent.listeners.append(self._on_transition)
        self._events: deque[dict[str, Any]] = deque(maxlen=100)
        self._camera_key: object = None
        self._camera_jpeg: bytes | None = None
        self._map_image: MapImage | None = None
        self._map_key: tuple[int, int] | None = None
        self._listing: dict[str, tuple[int, list[str]]] = {}
        self._wifi = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dashboard-wifi")
        #: The newest finished task already told as an event (goal reached, mission finished).
        self._last_report: dict[str, Any] | None = None
        #: Reads and prepares selected maps off the robot's thread, one at a time.
        self._loader = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dashboard-maps")
        #: The map being loaded or waiting for its swap (another selection is refused meanwhile).
        self._map_loading: str | None = None
        self.place_editor = PlaceEditor(self.maps)
        robot.add(_Pump(self), pump_rate_hz)
        self.recorder: VideoRecorder | None = None
        if self.sim is not None and self.camera is not None and driver_name(self.config, "camera") == "sim":
            # A client may open the camera view at any moment and expects a live picture at once: the simulated
            # camera renders while the dashboard runs (a headless run has none, and renders no frame for nobody).
            self.sim.camera_source.want("dashboard", lambda now: True)
        if self.camera is not None:
            camera = self.camera
            rate_hz = camera_rate_hz(self.config)
            self.recorder = VideoRecorder(self.config.data_dir / "media" / "videos", lambda: camera.latest,
                                          WallClock().wall_time, rate_hz=rate_hz,
                                          on_failure=lambda why: robot.event("video", why))
            robot.add(self.recorder, rate_hz)

    # -- the robot's thread ------------------------------------------------------------------------------
    def _pump(self, now: float) -> None:
        """Run the queued actions (`MAX_ACTIONS_PER_TICK` at most), report the agent's refusals, collect
        localization events."""
        for _ in range(MAX_ACTIONS_PER_TICK):
            try:
                what, action = self._actions.get_nowait()
            except queue.Empty:
                break
            try:
                action(now)
            except AtemrError as exc:
                self.robot.event("refused", f"{what}: {exc}")
            except Exception as exc:  # a failing action must not stop the others
                log.exception("dashboard action %s failed", what)
                self.robot.event("refused", f"{what}: {type(exc).__name__}: {exc}")
        for _ in range(len(self._watched)):
            command_id, trigger = self._watched.popleft()
            result = self.agent.result(command_id)
            if result is None:
                self._watched.append((command_id, trigger))
            elif result.decision == "requested":
                self.robot.event("autonomy", f"{trigger}: {result.reason}")
            elif not result.accepted:
                self.robot.event("refused", f"{trigger}: {result.reason}")
        for event in self.robot.parts.localization.drain_events():
            self.robot.event(f"localization {event.kind}", event.detail)
        reports = self.agent.task_reports
        if reports and reports[-1] is not self._last_report:
            self._last_report = reports[-1]
            self.robot.event(*plain_outcome(reports[-1], self.robot.parts.navigation.last_status))

    def _on_transition(self, record: TransitionRecord) -> None:
        """A step the robot asked the operator about and did not take (denied, or no answer in time) is said:
        the carer's "Go to place: accepted" otherwise stayed while the robot stood still."""
        if record.decision in ("denied", "timed_out"):
            self.robot.event("unconfirmed", plain_unconfirmed(record.trigger, record.decision, record.decided_by))

    def _queue(self, what: str, action: Callable[[float], object]) -> CommandResult:
        """Queue ``action(now)`` for the robot's thread; refused when `MAX_QUEUED_ACTIONS` wait already."""
        if self._actions.qsize() >= MAX_QUEUED_ACTIONS:
            return CommandResult.refused(f"{what}: the robot has {MAX_QUEUED_ACTIONS} requests waiting; try again")
        self._actions.put((what, action))
        return CommandResult.accepted()

    def _submit(self, trigger: str, **kwargs: Any) -> CommandResult:
        """Queue ``trigger`` for the agent if it may be taken in the current state; else refuse at once."""
        why = self.agent.precheck(trigger)
        if why is not None:  # the agent's own words stay on the Agent page; the carer reads plain ones
            return CommandResult.refused(plain_refusal(trigger, self.agent.state))
        command_id = self.agent.submit(trigger, origin="dashboard", **kwargs)
        with self._lock:
            self._watched.append((command_id, trigger))
        return CommandResult.accepted()

    # -- reading -----------------------------------------------------------------------------------------
    def _camera_frame(self) -> tuple[object, bytes] | None:
        """The newest camera frame and its JPEG, encoded once per frame whoever asks."""
        if self.camera is None:
            return None
        frame: NDArray[np.uint8] | None = self.camera.latest
        if frame is None:
            return None
        with self._lock:
            if frame is self._camera_key and self._camera_jpeg is not None:
                return frame, self._camera_jpeg
        data = jpeg(frame)
        with self._lock:
            self._camera_key, self._camera_jpeg = frame, data
        return frame, data

    def _listing_of(self, kind: str, folder: Path, names: Callable[[], list[str]]) -> list[str]:
        """A directory's listing, recomputed only when the directory changes."""
        try:
            stamp = folder.stat().st_mtime_ns
        except OSError:
            stamp = -1
        with self._lock:
            cached = self._listing.get(kind)
            if cached is not None and cached[0] == stamp:
                return list(cached[1])
        listing = names()
        with self._lock:
            self._listing[kind] = (stamp, listing)
        return list(listing)

    def missions(self) -> list[str]:
        """The mission files that can be started (their stems)."""
        folder = self.missions_dir
        return self._listing_of("missions", folder, lambda: sorted(p.stem for p in folder.glob("*.yaml")))

    def _navigation(self) -> tuple[NavStatus | None, Pose2D | None]:
        """The navigator's last status (with its paths) and goal."""
        nav = self.robot.parts.navigation
        return nav.last_status, nav.goal

    def _mission(self, snapshot: dict[str, Any]) -> MissionJson | None:
        """The running or last mission; None for a single goal, which runs as a one-step mission (`GOAL_TASK`) but
        is no mission to the carer: the robot's screen said "Doing the task 'goal'" and the Control page
        "goal: running 0%" for the whole drive. The state's ``goal`` and ``navigation`` describe it."""
        report = snapshot.get("task_progress")
        if not isinstance(report, dict) or report.get("mission") == GOAL_TASK:
            return None
        steps = report.get("steps") or []
        done = sum(1 for s in steps if s.get("status") in ("reached", "failed", "not run", "interrupted"))
        return {"name": report.get("mission"), "progress": round(done / len(steps), 3) if steps else 0.0,
                "state": report.get("outcome")}

    def state(self) -> RobotState:
        agent = self.agent.snapshot(transitions=0)
        parts = self.robot.parts
        pose = parts.localization.map_pose()
        scan = self.robot.devices.lidar.latest
        status, goal = self._navigation()
        running = status is not None and status.state == "RUNNING"
        agent_state = top_state(str(agent["state"]))
        wheels = parts.driver.feedback()
        last = parts.motion.last
        level1, level2 = status_levels(self.link.status)
        limits = self.pipeline.limits
        autonomy = self.agent.autonomy_state()
        return {
            "robot": self.config.secondary.robot_name,
            "agent_state": agent_state,
            "mode": agent["mode"] or self.inputs.mode,
            "simulation": self.sim is not None,
            "active_map": self.maps.active_name,
            "map_version": self.maps.version,
            "pose": pose_json(pose),
            "localization": self._localization(),
            "scan": points_json(scan_points(scan, pose)) if scan is not None and pose is not None else [],
            "depth_obstacles": points_json(parts.navigation.depth_obstacles()) if pose is not None else [],
            "global_path": points_json(status.global_path) if running and status is not None else [],
            "local_path": points_json(status.local_trajectory) if running and status is not None else [],
            "goal": pose_json(goal) if running and agent_state == "EXEC" else None,
            "navigation": navigation_json(status) if running and agent_state == "EXEC" and status is not None
            else None,
            "wheel_speeds": {"left_radps": round(wheels.left_radps, 3), "right_radps": round(wheels.right_radps, 3)},
            "emergency": bool(last is not None and (last.emergency or last.cliff_stop)),
            "stop_cause": self._stop_cause(),
            "level1": level1,
            "level2": level2,
            "system": system_json(parts.system_monitor.latest),
            "limits": {"linear_mps": limits.max_linear_mps, "angular_radps": limits.max_angular_radps},
            "awareness": bool(self.inputs.awareness),
            "wifi_ssid": self.link.network.ssid,
            "mapping": self.maps.slam is not None,
            "recording": self.recorder is not None and self.recorder.recording,
            "mission": self._mission(agent),
            "missions": self.missions(),
            "maps": self._listing_of("maps", self.store.dir, self.store.names),
            "places": [{"name": p.name, "x_m": round(p.pose.x_m, 3), "y_m": round(p.pose.y_m, 3),
                        "yaw_rad": round(p.pose.yaw_rad, 3), "kind": p.kind} for p in self.maps.places.values()],
            "battery": self._battery(),
            "events": self.robot.recent_events(EVENTS_SHOWN),
            "autonomy": {"level": autonomy["level"], "levels": autonomy["levels"], "timeout_s": autonomy["timeout_s"],
                         "pending": autonomy["pending"], "now": autonomy["now"]},
        }

    def _battery(self) -> BatteryJson | None:
        status = self.robot.parts.battery.status()
        if status is None:
            return None
        return {"percent": round(status.percent, 1), "voltage_v": round(status.voltage_v, 2), "level": status.level}

    def _localization(self) -> LocalizationJson:
        localization = self.robot.parts.localization
        status = localization.status
        return {"confidence": status.confidence, "limit": status.limit, "localized": status.localized,
                "state": status.state,
                "candidates": [{"x_m": round(h.pose.x_m, 3), "y_m": round(h.pose.y_m, 3),
                                "yaw_rad": round(h.pose.yaw_rad, 3), "agreement": round(h.agreement, 3)}
                               for h in localization.candidates[:MAX_CANDIDATES_SHOWN]],
                "looking_around": localization.wants_a_look}

    def _stop_cause(self) -> StopCause | None:
        """Why a safety layer holds the robot stopped, the most urgent first: a drop under its edge (or the floor
        sensors gone quiet, so a drop cannot be ruled out), an obstacle in the stop zone, the heartbeat between the
        cores lost, a CAN bus fault, a motor fault. The bus before the motors: when it fails the motors fall silent
        behind it and the driver latches that too, but what to mend is the bus (as the agent names it)."""
        parts = self.robot.parts
        last = parts.motion.last
        stops = self.inputs.safety_stops
        causes: list[tuple[bool, StopCause]] = [
            (last is not None and last.cliff_stop and last.cliff_blind, "floor_sensors"),
            (last is not None and last.cliff_stop, "cliff"),
            (last is not None and last.emergency, "obstacle"),
            (HEARTBEAT_STOP in stops, "heartbeat"),
            (CAN_BUS_STOP in stops, "bus"),
            (parts.driver.fault is not None, "motor"),
        ]
        return next((cause for held, cause in causes if held), None)

    def map_image(self) -> MapImage | None:
        """The drawable map, rendered once per map version."""
        grid = self.maps.drawable()
        if grid is None:
            return None
        key = (self.maps.version, id(grid))
        with self._lock:
            if self._map_key == key and self._map_image is not None:
                return self._map_image
        image = render_map(grid, self.maps.version)
        with self._lock:
            self._map_key, self._map_image = key, image
        return image

    def camera_jpeg(self) -> bytes | None:
        frame = self._camera_frame()
        return None if frame is None else frame[1]

    def camera_frame(self) -> NDArray[np.uint8] | None:
        return None if self.camera is None else self.camera.latest

    def secondary_screen_png(self) -> bytes | None:
        board = self.robot.parts.secondary_board
        return None if board is None else board.screen_png(scale=2, color=True)

    def agent_snapshot(self) -> dict[str, Any] | None:
        return self.agent.snapshot()

    # -- driving -----------------------------------------------------------------------------------------
    def joystick(self, twist: Twist) -> CommandResult:
        if not isinstance(twist, Twist) or not _finite(twist.linear_mps, twist.angular_radps):
            return CommandResult.refused(f"joystick: a finite velocity is needed, got {brief(twist)}")
        if self.inputs.mode == "AUTO":
            return CommandResult.refused("joystick ignored in AUTO: switch to MANUAL to drive")
        self.inputs.operate(twist, self.robot.clock.now())
        self._take_over_the_look()  # STOP in MANUAL is a zero joystick command: it ends the look too
        return CommandResult.accepted()

    def _take_over_the_look(self) -> None:
        """The operator drives (or stops, or maps): the robot no longer turns by itself after FIND POSITION, now or
        later (`LocalizationPipeline.stop_looking`)."""
        localization = self.robot.parts.localization
        if localization is not None and localization.wants_a_look:
            self._queue("take over the look around", lambda now: localization.stop_looking())

    def set_mode(self, mode: Mode) -> CommandResult:
        if mode not in ("MANUAL", "AUTO"):
            return CommandResult.refused(f"mode must be MANUAL or AUTO, got {brief(mode)}")
        state = self.agent.state
        if state == f"IDLE.{mode}":
            return CommandResult.accepted()
        if mode == "AUTO":  # the guards answer now: AUTO refused with the reason, not accepted then undone
            why = self.agent.refusal("set_auto")
            if why is not None:
                return CommandResult.refused(plain_guard_refusal("set_auto", why, self.robot.parts.localization.status))
        return self._submit("set_auto" if mode == "AUTO" else "set_manual")

    def set_goal(self, goal: Pose2D) -> CommandResult:
        why = _pose_ok(goal, "goal")
        if why is not None:
            return CommandResult.refused(why)
        if self.agent.state == "IDLE.MANUAL":
            return CommandResult.refused("switch to AUTO first")
        if self.agent.precheck("goal") is None:
            if self.agent.context.navigation is None:
                return CommandResult.refused("navigation is not available on this robot")
            verdict = self.robot.parts.navigation.goal_check(goal)  # the agent's navigation, with the refusal's code
            if not verdict.ok:
                return CommandResult.refused(plain_goal_refusal(verdict, self.robot.parts.localization.status))
        return self._submit("goal", goal=goal)

    def set_initial_pose(self, pose: Pose2D) -> CommandResult:
        why = _pose_ok(pose, "initial pose")
        if why is not None:
            return CommandResult.refused(why)
        localization = self.robot.parts.localization
        if localization is None:
            return CommandResult.refused("this robot has no localization")
        grid = self.maps.active
        if grid is None:
            return CommandResult.refused("no active map: select or build a map first")
        row, col = grid.world_to_cell(pose.x_m, pose.y_m)
        if not grid.contains(row, col):
            return CommandResult.refused(f"({pose.x_m:.2f}, {pose.y_m:.2f}) is outside the map {self.maps.active_name}")
        return self._queue("initial pose", lambda now: localization.set_initial_pose(now, pose))

    def localize_globally(self) -> CommandResult:
        localization = self.robot.parts.localization
        if localization is None:
            return CommandResult.refused("this robot has no localization")
        if self.maps.active is None:
            return CommandResult.refused("no active map: select or build a map first")
        # The operator asked the robot to find itself: in MANUAL, where `DriveJoystick` drives it, an ambiguous
        # answer turns it in place (a mission's relocalize step turns it in AUTO).
        look = self.agent.state == "IDLE.MANUAL"
        return self._queue("global localization",
                           lambda now: localization.start_global(now, "requested by the operator", look_around=look))

    def cancel_goal(self) -> CommandResult:
        return self._submit("cancel")

    # -- mapping -----------------------------------------------------------------------------------------
    def begin_mapping(self) -> CommandResult:
        if self.agent.state == "IDLE.AUTO":
            return CommandResult.refused("mapping starts in MANUAL: switch to MANUAL first")
        result = self._submit("begin_mapping")
        if result.ok:
            self._take_over_the_look()
        return result

    def end_mapping(self) -> CommandResult:
        if not self.agent.state.startswith("MAPPING") or self.maps.slam is None:
            return CommandResult.refused("no mapping session is running")
        self.maps.pause()
        return CommandResult.accepted()

    def save_map(self, name: str) -> CommandResult:
        from atemr.io.map_store import clean_name

        try:
            clean = clean_name(name)
        except ConfigError as exc:
            return CommandResult.refused(exc.reason)
        if clean != name:
            return CommandResult.refused(f"invalid map name {brief(name)}: use {brief(clean)}")
        if name in self.store.builtins:
            return CommandResult.refused(f"'{name}' is a built-in map and cannot be replaced; choose another name")
        if self.store.exists(name):
            return CommandResult.refused(f"a map named '{name}' already exists; choose another name")
        return self._submit("save_map", name=name)

    def discard_map(self) -> CommandResult:
        return self._submit("discard_map")

    def select_map(self, name: str) -> CommandResult:
        """Read and prepare map ``name`` in the gateway's worker (the robot goes on meanwhile), then queue the
        swap for the robot's thread. Answers when the map is ready (or refused: unreadable, too large, ...),
        or after `MAP_WAIT_S` with "still loading" (the outcome is then an event)."""
        if not isinstance(name, str) or not self.store.exists(name):
            return CommandResult.refused(f"no map named {brief(name)}; known maps: {', '.join(self.store.names())}")
        top = self.agent.state.split(".")[0]
        if top != "IDLE":
            return CommandResult.refused(f"maps are switched in IDLE only (now {self.agent.state})")
        with self._lock:
            if self._map_loading is not None:
                return CommandResult.refused(f"map {self._map_loading} is still loading: select again when it is "
                                             "active")
            if name == self.maps.active_name:
                return CommandResult.accepted()
            self._map_loading = name
            waiting = [True]  # the request answers; after MAP_WAIT_S the worker's callback reports instead
        try:
            future: Future[PreparedMap] = self._loader.submit(self.maps.prepare, name)
        except RuntimeError:  # the gateway is closing
            with self._lock:
                self._map_loading = None
            return CommandResult.refused("the robot is stopping")

        def done(f: Future[PreparedMap]) -> None:
            with self._lock:
                if waiting[0]:
                    return
            result = self._map_ready(name, f)
            if not result.ok:
                self.robot.event("refused", f"select map: {result.reason}")

        future.add_done_callback(done)
        try:
            future.exception(timeout=MAP_WAIT_S)
        except CancelledError:  # the gateway closed before the load began
            with self._lock:
                self._map_loading = None
            return CommandResult.refused("the robot is stopping")
        except FutureTimeout:
            with self._lock:
                if not future.done():
                    waiting[0] = False
                    return CommandResult(True, f"still loading map {name}; it becomes active when it is ready "
                                               "(see the events)")
        return self._map_ready(name, future)

    def _map_ready(self, name: str, future: Future[PreparedMap]) -> CommandResult:
        """A finished load: queue the swap, or refuse with the reason (the loading slot is freed then)."""
        try:
            prepared = future.result()
        except ConfigError as exc:
            reason = f"map {name} cannot be loaded: {exc.reason}"
        except Exception as exc:  # a broken map must not leave the slot taken
            log.exception("loading map %s failed", name)
            reason = f"map {name} cannot be loaded: {type(exc).__name__}: {brief_text(str(exc), 200)}"
        else:
            queued = self._queue("select map", lambda now: self._swap_map(prepared))
            if queued.ok:
                return queued
            reason = queued.reason
        with self._lock:
            self._map_loading = None
        return CommandResult.refused(reason)

    def _swap_map(self, prepared: PreparedMap) -> None:
        """Robot's thread: make the prepared map active, if the agent is still in IDLE (cheap: assignments)."""
        try:
            state = self.agent.state
            if state.split(".")[0] != "IDLE":
                self.robot.event("refused", f"select map: maps are switched in IDLE only (now {state}); "
                                            f"map {prepared.name} not selected")
                return
            self.maps.swap(prepared)
        finally:
            with self._lock:
                self._map_loading = None

    def validate_map(self, yaml_path: Path) -> CommandResult:
        from atemr.io.sim.maps import load_map

        try:
            load_map(Path(yaml_path), max_cells=self.store.max_cells)
        except ConfigError as exc:
            return CommandResult.refused(f"not a valid ROS map: {exc.reason}")
        return CommandResult.accepted()

    def maps_changed(self) -> None:
        """Refresh the map list; a deleted active map stays in use (in memory) until another is selected."""
        with self._lock:
            self._listing.pop("maps", None)
        active = self.maps.active_name
        if active is not None and not self.store.exists(active):
            self.robot.event("map", f"the active map {active} was deleted; it stays in use until another is selected")

    def files_in_use(self) -> Collection[Path]:
        writer = self.robot.parts.trace
        writing = None if writer is None else writer.writing
        return () if writing is None else (writing,)

    # -- places (`atemr.robot.places`) ---------------------------------------------------------------------
    def go_to_place(self, name: str) -> CommandResult:
        place = self.place_editor.find(name)
        if isinstance(place, str):
            return CommandResult.refused(place)
        result = self.set_goal(place.pose)
        if result.ok:
            self.robot.event("places", f"going to {place.name}")
        return result

    def save_place(self, name: str, pose: Pose2D, kind: str = "place", previous: str | None = None) -> CommandResult:
        return self.place_editor.save(name, pose, kind, previous)

    def delete_place(self, name: str) -> CommandResult:
        return self.place_editor.delete(name)

    # -- routines (`atemr.robot.routines`) -----------------------------------------------------------------
    def routines(self) -> dict[str, Any] | None:
        runner = self.robot.parts.routines
        return None if runner is None else runner.snapshot()

    def _change_routines(self, change: Callable[[RoutineBook], RoutineBook], what: str, done: str) -> CommandResult:
        """Apply ``change`` to the routines in force and store the result (the runner reads it at its next tick);
        a refusal (``what``: its reason) stores nothing. ``done`` is the event, which the alerts show after
        "Routine"."""
        runner = self.robot.parts.routines
        if runner is None:
            return CommandResult.refused("this robot runs no routines")
        try:
            book = change(runner.store.load())
            runner.store.save(book)
            runner.reload()
        except ConfigError as exc:
            return CommandResult.refused(f"{what}: {exc.reason}")
        except OSError as exc:
            return CommandResult.refused(f"{what}: not saved: {exc.strerror}")
        self.robot.event("routine", done)
        return CommandResult.accepted()

    def save_routine(self, routine: dict[str, Any], previous: str | None = None) -> CommandResult:
        from atemr.domain.routines import Routine

        def change(book: RoutineBook) -> RoutineBook:
            new = Routine.from_json(routine, "routine")
            if new.mission not in self.missions():
                raise ConfigError(f"no mission named {brief(new.mission)}; missions: {', '.join(self.missions())}",
                                  path="routine.mission")
            if previous is not None and previous != new.name:
                book = book.without(previous)
                if book.get(new.name) is not None:
                    raise ConfigError(f"a routine named {new.name!r} exists already", path="routine.name")
            elif previous is None and book.get(new.name) is not None:
                raise ConfigError(f"a routine named {new.name!r} exists already", path="routine.name")
            return book.with_routine(new)

        name = routine.get("name") if isinstance(routine, dict) else routine
        renamed = f" (was {brief(previous)})" if previous not in (None, name) else ""
        return self._change_routines(change, f"routine {brief(name)}", f"{brief(name)} saved{renamed}")

    def delete_routine(self, name: str) -> CommandResult:
        return self._change_routines(lambda book: book.without(name), f"delete routine {brief(name)}",
                                     f"{brief(name)} deleted")

    def set_routines_timezone(self, timezone: str) -> CommandResult:
        from atemr.domain.routines import zone

        def change(book: RoutineBook) -> RoutineBook:
            zone(timezone)
            return RoutineBook(timezone, book.routines)

        return self._change_routines(change, f"routines time zone {brief(timezone)}", f"time zone {timezone} set")

    # -- settings ----------------------------------------------------------------------------------------
    def set_limits(self, linear_mps: float, angular_radps: float) -> CommandResult:
        changes = {"max_linear_mps": linear_mps, "max_angular_radps": angular_radps}
        try:
            checked_limits(changes, self.pipeline.limits)
            applied = self.pipeline.set_limits(changes)
        except ConfigError as exc:
            return CommandResult.refused(f"speed limits not changed: {exc}")
        try:
            self.settings.update("motion", {"max_linear_mps": applied.max_linear_mps,
                                            "max_angular_radps": applied.max_angular_radps})
        except OSError as exc:
            return CommandResult.refused(f"speed limits applied but not saved: {exc.strerror}")
        self.robot.event("settings", f"speed limits {applied.max_linear_mps:g} m/s, "
                                     f"{applied.max_angular_radps:g} rad/s")
        return CommandResult.accepted()

    def set_awareness(self, enabled: bool) -> CommandResult:
        if not isinstance(enabled, bool):
            return CommandResult.refused(f"awareness is on or off (true/false), got {brief(enabled)}")
        self.inputs.awareness = enabled
        try:
            self.settings.update("reactive", {"awareness": enabled})
        except OSError as exc:
            return CommandResult.refused(f"awareness applied but not saved: {exc.strerror}")
        self.robot.event("settings", f"awareness {'on' if enabled else 'off'}")
        return CommandResult.accepted()

    def set_wifi(self, ssid: str, password: str) -> CommandResult:
        if not isinstance(ssid, str) or not 1 <= len(ssid.encode()) <= 32:
            return CommandResult.refused("the WiFi name (SSID) is 1-32 bytes")
        if not isinstance(password, str) or not 8 <= len(password.encode()) <= 63:
            return CommandResult.refused("the WiFi password is 8-63 characters")
        network = self.link.network
        future: Future[None] = self._wifi.submit(network.connect, ssid, password)

        def done(f: Future[None]) -> None:
            exc = f.exception()
            if exc is None:
                self.robot.event("wifi", f"joined {ssid}")
            else:
                self.robot.event("wifi", f"joining {ssid} failed: {exc}")

        future.add_done_callback(done)
        try:
            error = future.exception(timeout=WIFI_WAIT_S)
        except FutureTimeout:
            return CommandResult(True, f"still joining {ssid}; the result will be in the events")
        return _ok(error is None, f"joining {ssid} failed: {error}")

    # -- media and missions ------------------------------------------------------------------------------
    def capture_image(self) -> CommandResult:
        # One way to capture: the same as the agent's CaptureImage leaf (RobotPort.capture_image).
        try:
            self.robot.parts.port.capture_image("capture")
        except AtemrError as exc:
            return CommandResult.refused(str(exc))
        return CommandResult.accepted()

    def record_video(self, on: bool) -> CommandResult:
        if self.recorder is None:
            return CommandResult.refused("this robot has no camera to record")
        try:
            path = self.recorder.begin() if on else self.recorder.end()
        except AtemrError as exc:
            return CommandResult.refused(str(exc))
        self.robot.event("video", f"{'recording' if on else 'recorded'} {path.name}")
        return CommandResult.accepted()

    def start_mission(self, name: str) -> CommandResult:
        from atemr.trees.missions import load_mission

        if not isinstance(name, str) or name not in self.missions():
            known = ", ".join(self.missions()) or "none"
            return CommandResult.refused(f"no mission named {brief(name)}; known: {known}")
        if self.agent.precheck("start_mission") is not None:  # the agent's words stay on the Agent page
            return CommandResult.refused("switch to AUTO first" if self.agent.state == "IDLE.MANUAL"
                                         else plain_refusal("start_mission", self.agent.state))
        try:
            mission = load_mission(self.missions_dir / f"{name}.yaml")
        except ConfigError as exc:
            return CommandResult.refused(f"mission {brief(name)} is not valid: {exc}")
        why = self.agent.refusal("start_mission", mission=mission)
        if why is not None:
            return CommandResult.refused(plain_guard_refusal("start_mission", why,
                                                             self.robot.parts.localization.status))
        return self._submit("start_mission", mission=mission)

    def stop_mission(self) -> CommandResult:
        return self._submit("cancel")

    # -- agent studio: autonomy and reload -------------------------------------------------------------
    def answer_transition(self, request_id: int, confirm: bool, by: str) -> CommandResult:
        why = self.agent.answer(request_id, confirm, by=by)
        if why is not None:
            return CommandResult.refused(why)
        self.robot.event("autonomy", f"request {request_id} {'confirmed' if confirm else 'denied'} by {by}")
        return CommandResult.accepted()

    def set_autonomy(self, level: str, by: str) -> CommandResult:
        try:
            applied = self.agent.set_autonomy(level, by=by)
        except ConfigError as exc:
            return CommandResult.refused(exc.reason)
        self.robot.event("autonomy", f"level {applied} (set by {by})")
        return CommandResult.accepted()

    def reload_agent(self) -> CommandResult:
        self.robot.parts.reload_watcher.request()
        return CommandResult.accepted()

    # -- simulation panel --------------------------------------------------------------------------------
    def _sim_action(self, what: str, action: Callable[[], object]) -> CommandResult:
        if self.sim is None:
            return CommandResult.refused("not a simulation")
        future = self.sim.submit(action)

        def done(f: Future[object]) -> None:
            exc = f.exception()
            if exc is not None:
                self.robot.event("simulation", f"{what} failed: {exc}")

        future.add_done_callback(done)
        return CommandResult.accepted()

    def sim_button(self, hold_s: float) -> CommandResult:
        board = self.robot.parts.secondary_board
        if self.sim is None or board is None:
            return CommandResult.refused("not a simulation")
        if not _finite(hold_s) or not 0 < hold_s <= MAX_BUTTON_HOLD_S:
            return CommandResult.refused(f"a button press lasts 0-{MAX_BUTTON_HOLD_S:g} s, got {brief(hold_s)}")
        board.button.hold(float(hold_s))
        return CommandResult.accepted()

    def _in_world(self, x_m: float, y_m: float) -> str | None:
        if not _finite(x_m, y_m):
            return f"a position must be finite numbers, got ({brief(x_m)}, {brief(y_m)})"
        if self.sim is None:
            return "not a simulation"
        world = self.sim.world.map
        if not world.contains(*world.world_to_cell(x_m, y_m)):
            return f"({x_m:.2f}, {y_m:.2f}) is outside the simulated world"
        return None

    def sim_drop_obstacle(self, x_m: float, y_m: float) -> CommandResult:
        if self.sim is None:
            return CommandResult.refused("not a simulation")
        why = self._in_world(x_m, y_m)
        if why is not None:
            return CommandResult.refused(why)
        sim = self.sim
        return self._sim_action("drop obstacle", lambda: sim.drop_obstacle(float(x_m), float(y_m)))

    def sim_kidnap(self, pose: Pose2D) -> CommandResult:
        if self.sim is None:
            return CommandResult.refused("not a simulation")
        why = _pose_ok(pose, "kidnap pose") or self._in_world(pose.x_m, pose.y_m)
        if why is not None:
            return CommandResult.refused(why)
        sim = self.sim
        contact = sim.clearance_at(pose.x_m, pose.y_m)
        if contact.clearance_m < 0:
            return CommandResult.refused(f"({pose.x_m:.2f}, {pose.y_m:.2f}) overlaps {contact.what}")
        return self._sim_action("kidnap", lambda: sim.kidnap(pose))

    def close(self) -> None:
        """Stop the WiFi and map workers (done by the robot's shutdown; idempotent). A map being read is left
        to finish on its own; nothing swaps it in any more."""
        self._wifi.shutdown(wait=False)
        self._loader.shutdown(wait=False, cancel_futures=True)


__all__ = ["MAP_WAIT_S", "MAX_ACTIONS_PER_TICK", "MAX_QUEUED_ACTIONS", "PUMP_RATE_HZ", "RobotGatewayImpl"]
