"""The agent's ports implemented over the assembled robot's parts: `RobotPortImpl` and `SecondaryLinkPort`.

Everything the agent's leaves and guards ask of the robot goes through here: velocity onto the motion
inputs, health from the health board, pose from localization (odometry before it), camera frames to the
media directory, mapping to the map service, and the 0x153 status and 0x150 power byte to the secondary
link. The ports themselves are the agent's (`atemr.trees.ports`); their adapters live in `atemr.robot`,
the one layer that may know both the agent and the parts. Navigation's adapter is
`atemr.robot.navigator_port.NavigatorPort`.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from atemr.domain.status import BatteryStatus, ComponentHealth, LocalizationStatus, PowerState
from atemr.errors import HardwareError
from atemr.io.can import PrimaryStatus
from atemr.io.secondary_link import SecondaryLink
from atemr.msgs import Pose2D, Twist
from atemr.robot.health import HealthBoard
from atemr.robot.inputs import MotionInputs
from atemr.robot.mapping import MapService
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.trees.ports import Mode, VelocitySource


def jpeg(frame: NDArray[np.uint8], quality: int = 85) -> bytes:
    """An RGB frame as JPEG bytes."""
    buffer = io.BytesIO()
    Image.fromarray(frame, "RGB").save(buffer, format="JPEG", quality=quality)
    return buffer.getvalue()


class RobotPortImpl:
    """`atemr.trees.ports.RobotPort` over the robot (built by `atemr.robot.build_robot`)."""

    def __init__(self, *, now: Callable[[], float], inputs: MotionInputs, health: HealthBoard,
                 localization: LocalizationPipeline, maps: MapService,
                 camera: Callable[[], NDArray[np.uint8] | None], images_dir: Path,
                 wall_time: Callable[[], float], battery: Callable[[], BatteryStatus | None],
                 event: Callable[[str, str], None]) -> None:
        self._now = now
        self.inputs = inputs
        self.health_board = health
        self.localization = localization
        self.maps = maps
        self.camera = camera
        self.images_dir = images_dir
        self.wall_time = wall_time
        self._battery = battery
        self._event = event

    def command_velocity(self, source: VelocitySource, twist: Twist, now: float) -> None:
        self.inputs.offer(source, twist, now)

    def stop_motors(self) -> None:
        self.inputs.zero(self._now(), ("navigation", "agent"))

    def set_mode(self, mode: Mode) -> None:
        self.inputs.mode = mode

    def health(self) -> Mapping[str, ComponentHealth]:
        return self.health_board.collect()

    def pose(self) -> Pose2D | None:
        return self.localization.map_pose()

    def odom_pose(self) -> Pose2D | None:
        return self.localization.odom_pose

    def joystick(self) -> tuple[Twist, float] | None:
        latest = self.inputs.operator()
        return None if latest is None else (latest.twist, latest.t)

    def capture_image(self, label: str) -> str:
        frame = self.camera()
        if frame is None:
            raise HardwareError("no camera frame to capture (is the camera on?)", component="camera")
        stamp = datetime.fromtimestamp(self.wall_time(), UTC).strftime("%Y%m%d-%H%M%S-%f")
        safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in label)[:40] or "capture"
        path = self.images_dir / f"{stamp}-{safe}.jpg"
        try:
            self.images_dir.mkdir(parents=True, exist_ok=True)
            path.write_bytes(jpeg(frame))
        except OSError as exc:
            raise HardwareError(f"cannot save the image: {exc.strerror}", component="camera") from None
        return str(path)

    def localization_status(self) -> LocalizationStatus | None:
        return self.localization.status

    def relocalize(self, now: float) -> None:
        self.localization.start_global(now)

    def wants_a_look(self) -> bool:
        return self.localization.wants_a_look

    def begin_mapping(self) -> None:
        self.maps.begin()

    def end_mapping(self, save_as: str | None) -> None:
        self.maps.end(save_as, self._now())

    def clear_faults(self) -> str | None:
        return self.health_board.clear_faults()

    def battery(self) -> BatteryStatus | None:
        return self._battery()

    def report(self, kind: str, text: str) -> None:
        self._event(kind, text)


class SecondaryLinkPort:
    """The agent's `LinkPort` over the real `atemr.io.secondary_link.SecondaryLink` (the primary's end of the
    CAN link), ticked by the same scheduler: ``Agent(spec, robot_port, SecondaryLinkPort(link))``.

    The link itself sends the 0x157 heartbeat every 0.5 s, and re-sends 0x153 and 0x150 at 2 Hz and at once
    on change; the agent only sets what they carry and reads what came back.
    """

    def __init__(self, link: SecondaryLink) -> None:
        self.link = link

    def publish_status(self, status: PrimaryStatus) -> None:
        self.link.set_status(status.agent, status.hardware, status.state)

    def set_power_state(self, state: PowerState) -> None:
        self.link.set_power_state(state)

    def power_off_requested(self) -> bool:
        return bool(self.link.power_off_requested)

    def heartbeat_ok(self) -> bool:
        return bool(self.link.heartbeat_ok)
