"""The boundary between the dashboard and the robot: what the dashboard reads and what it commands.

The dashboard never touches the agent, the skills or the bus. It reads one JSON-able snapshot
(`RobotGateway.state`) at 10 Hz plus a few binary products (map image, camera JPEG and raw frame, the secondary
core's screen), and every operator action is one method that returns a `CommandResult`: ok, or a
refusal reason the page shows as it is ("refused: switch to AUTO first"). `atemr.robot.gateway.RobotGatewayImpl`
implements this protocol over the real robot; UI tests use small fakes of their own. Methods may
be called from the web server's threads, so an implementation must be thread-safe (queue the command
for the agent's next tick and answer from what it can check at once).

The snapshot's contract is one type, `atemr.ui.state.RobotState`, shared by the robot, the pages and the
tests.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from atemr.msgs import Pose2D, Twist
from atemr.ui.state import Mode, RobotState


@dataclass(frozen=True)
class CommandResult:
    """The robot's answer to a command: accepted, or refused with a reason an operator can act on."""

    ok: bool
    reason: str = ""

    @classmethod
    def accepted(cls) -> CommandResult:
        return cls(True)

    @classmethod
    def refused(cls, reason: str) -> CommandResult:
        return cls(False, reason)

    def to_json(self) -> dict[str, Any]:
        return {"ok": self.ok, "reason": self.reason}


@dataclass(frozen=True)
class MapImage:
    """The active map (or the map being built) as the browser draws it.

    ``png`` is the occupancy grid rendered as an image (row 0 is the top, i.e. the largest y);
    ``origin`` is the map-frame pose of the bottom-left pixel, as in ROS map_server.
    """

    png: bytes
    width_px: int
    height_px: int
    resolution_m: float
    origin: Pose2D
    version: int

    def meta(self) -> dict[str, Any]:
        return {
            "width_px": self.width_px, "height_px": self.height_px, "resolution_m": self.resolution_m,
            "origin": {"x_m": self.origin.x_m, "y_m": self.origin.y_m, "yaw_rad": self.origin.yaw_rad},
            "version": self.version,
        }


@runtime_checkable
class RobotGateway(Protocol):
    """Everything the dashboard needs from the robot."""

    # -- reading -----------------------------------------------------------------------------------
    def state(self) -> RobotState:
        """The JSON-able snapshot (`RobotState`); cheap (called at 10 Hz)."""
        ...

    def map_image(self) -> MapImage | None:
        """The map to draw (the growing one while mapping), or None when there is none."""
        ...

    def camera_jpeg(self) -> bytes | None:
        """The newest camera frame as JPEG (at least 640×480), or None when the camera is off."""
        ...

    def camera_frame(self) -> NDArray[np.uint8] | None:
        """The newest camera frame as RGB (height × width × 3), or None when the camera is off: the same
        frame `camera_jpeg` encodes, for the WebRTC sender, which encodes video itself. Must not block (it
        is read from the drive video's own event loop); the array is never changed once handed out."""
        ...

    def secondary_screen_png(self) -> bytes | None:
        """The secondary core's 128×64 screen as PNG (simulation), or None."""
        ...

    def agent_snapshot(self) -> dict[str, Any] | None:
        """The agent for the Agent view (sent at 10 Hz only while someone has that page open), or None.

        The shape of `atemr.fsm.agent.Agent.snapshot` plus an optional ``machine``:
        ``state`` (e.g. ``"IDLE.MANUAL"``), ``mode``, ``valid_triggers``, ``task``, ``error``,
        ``tree`` and ``monitor`` (nested ``{name, type, status, ticks, feedback, reason?, children?}``),
        ``transitions`` (``[{t, trigger, source, dest, accepted, reason, origin, decision, decided_by}]``),
        ``blackboard`` (``{key: {value, by, t}}``: every key, the client that gave it its value and when),
        ``commands``, ``errors``, ``machine`` (``{"states": [name, ...], "transitions": [{trigger, source, dest,
        autonomy?}]}``), ``autonomy`` (as in `state`) and ``reloads`` (``[{kind, file, t, status, reason, diff,
        error, ...}]``: the hot-reload requests, `atemr.fsm.reload.ReloadReport`).
        """
        ...

    # -- driving -----------------------------------------------------------------------------------
    def joystick(self, twist: Twist) -> CommandResult:
        """An operator velocity command; ignored by the robot in AUTO mode, expires after 0.5 s."""
        ...

    def set_mode(self, mode: Mode) -> CommandResult:
        """MANUAL or AUTO; AUTO is refused unless every level-1 state is OK."""
        ...

    def set_goal(self, goal: Pose2D) -> CommandResult:
        """A navigation goal in the map frame (AUTO only; refused outside the map or in an obstacle)."""
        ...

    def set_initial_pose(self, pose: Pose2D) -> CommandResult:
        """Where the robot is, for the localization."""
        ...

    def localize_globally(self) -> CommandResult:
        """The robot finds its pose on the active map by itself (global localization), when the operator does
        not know it either: after a map switch, or when the robot was carried elsewhere."""
        ...

    def cancel_goal(self) -> CommandResult:
        ...

    # -- mapping -----------------------------------------------------------------------------------
    def begin_mapping(self) -> CommandResult:
        """Start a mapping session (MANUAL only)."""
        ...

    def end_mapping(self) -> CommandResult:
        """Stop adding scans; the map waits for `save_map` or `discard_map`."""
        ...

    def save_map(self, name: str) -> CommandResult:
        """Store the map built under ``name`` (it becomes the active map)."""
        ...

    def discard_map(self) -> CommandResult:
        ...

    def select_map(self, name: str) -> CommandResult:
        """Make the stored map ``name`` the active one. The map is read off the robot's control loop; the answer
        comes when it is ready (or refused), or says it is still loading (the outcome is then an event)."""
        ...

    def validate_map(self, yaml_path: Path) -> CommandResult:
        """Check an uploaded ROS map (``name.yaml`` beside its image) before the dashboard stores it."""
        ...

    def maps_changed(self) -> None:
        """Tell the robot the map directory changed (an upload or a delete), so its list is fresh."""
        ...

    def files_in_use(self) -> Collection[Path]:
        """The files the robot is writing now (its recording's current part): the media page lists them as being
        recorded and refuses to delete them. Called from the web server's threads; must not block."""
        ...

    # -- places ------------------------------------------------------------------------------------
    def go_to_place(self, name: str) -> CommandResult:
        """Drive to the active map's place ``name`` (AUTO only, as a goal; refused with the closest names)."""
        ...

    def save_place(self, name: str, pose: Pose2D, kind: str = "place", previous: str | None = None) -> CommandResult:
        """Add place ``name`` at ``pose`` on the active map, or (``previous``) move and/or rename that place;
        stored with the map at once."""
        ...

    def delete_place(self, name: str) -> CommandResult:
        ...

    # -- routines ----------------------------------------------------------------------------------
    def routines(self) -> dict[str, Any] | None:
        """The care routines for the Routines page (`atemr.robot.routines.RoutineRunner.snapshot`: ``timezone``,
        ``now``, ``routines`` with ``schedule`` and ``next``, ``running``, ``history``, ``error``), or None."""
        ...

    def save_routine(self, routine: dict[str, Any], previous: str | None = None) -> CommandResult:
        """Add a routine (``{name, mission, at | every_min+from+to, days, enabled}``, as in the routines file), or
        replace ``previous``; checked whole before it is stored."""
        ...

    def delete_routine(self, name: str) -> CommandResult:
        ...

    def set_routines_timezone(self, timezone: str) -> CommandResult:
        """The IANA time zone the routines' times are in (``Europe/Berlin``)."""
        ...

    # -- settings ----------------------------------------------------------------------------------
    def set_limits(self, linear_mps: float, angular_radps: float) -> CommandResult:
        """New speed limits, applied at once without a restart, persisted; a refusal keeps the old ones."""
        ...

    def set_awareness(self, enabled: bool) -> CommandResult:
        """Turn the reactive engine on or off."""
        ...

    def set_wifi(self, ssid: str, password: str) -> CommandResult:
        """Join another WiFi network."""
        ...

    # -- media and missions ------------------------------------------------------------------------
    def capture_image(self) -> CommandResult:
        """Save the current camera frame under ``data_dir/media/images``."""
        ...

    def record_video(self, on: bool) -> CommandResult:
        """Start or stop recording the camera under ``data_dir/media/videos``."""
        ...

    def start_mission(self, name: str) -> CommandResult:
        ...

    def stop_mission(self) -> CommandResult:
        ...

    # -- agent studio --------------------------------------------------------------------------------
    def answer_transition(self, request_id: int, confirm: bool, by: str) -> CommandResult:
        """Confirm or deny the transition waiting for the operator (``by``: the user name, recorded)."""
        ...

    def set_autonomy(self, level: str, by: str) -> CommandResult:
        """Set the robot's autonomy level (off, low, high, full)."""
        ...

    def reload_agent(self) -> CommandResult:
        """Re-read the agent document now (validated; applied in IDLE, deferred from other states)."""
        ...

    # -- simulation panel --------------------------------------------------------------------------
    def sim_button(self, hold_s: float) -> CommandResult:
        """Press the secondary core's button for ``hold_s`` seconds (1 s: power on, 5 s: power off)."""
        ...

    def sim_drop_obstacle(self, x_m: float, y_m: float) -> CommandResult:
        """Put an obstacle in the simulated world at a map-frame point."""
        ...

    def sim_kidnap(self, pose: Pose2D) -> CommandResult:
        """Move the simulated robot without telling its localization."""
        ...


NO_ROBOT = CommandResult.refused("no robot is connected to the dashboard")
