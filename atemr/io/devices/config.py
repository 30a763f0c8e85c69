"""The ``devices:`` section: which driver runs each of the robot's devices, and its settings.

One file describes one robot. ``driver: auto`` (the default) picks the simulator's device in simulation
(``simulation: true``) and the real driver on the robot; naming a driver mixes them, for example real
motors with a simulated lidar on the bench::

    simulation: false
    devices:
      lidar:  {driver: rplidar, port: /dev/ttyUSB0, baudrate: 115200, pose: [0.10, 0.0, 0.0]}
      imu:    {driver: wt901, port: /dev/ttyUSB1, baudrate: 9600}
      camera: {driver: opencv, source: "0"}    # a V4L2 index, a device path, a video file or an rtsp/http URL;
                                               # realsense: the D415's colour stream
      depth:  {driver: realsense}              # the D415 (the realsense extra); none: no depth camera
      motors: {driver: rmd, protocol: v1}      # or emulated
      secondary: {driver: esp32}               # or emulated

The key and driver names are part of the interface: documentation and other tools rely on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

#: Drivers that stand for the simulator (a device kind's ``sim``, the CAN devices' ``emulated``).
SIMULATED_DRIVERS = frozenset({"sim", "emulated"})


def _check_pose(pose: tuple[float, ...], what: str) -> None:
    if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
        raise ValueError(f"{what} must be [x_m, y_m, yaw_rad], three finite numbers, got {list(pose)}")


@dataclass(frozen=True)
class LidarDeviceConfig:
    """The 2D lidar: an RPLidar A2M8 on USB serial (SLAMTEC protocol), or the simulator's."""

    driver: Literal["auto", "sim", "rplidar"] = field(default="auto", metadata={
        "help": "auto: sim in simulation, rplidar on the robot"})
    port: str = field(default="/dev/ttyUSB0", metadata={"help": "serial port (udev: /dev/rplidar)"})
    baudrate: int = field(default=115200, metadata={"min": 9600, "max": 2_000_000, "help": "A2M8: 115200"})
    pose: tuple[float, ...] = field(default=(0.10, 0.0, 0.0), metadata={
        "help": "mounting pose in the base frame: [x_m, y_m, yaw_rad] (yaw: the lidar's forward axis); "
                "KAY's is 10 cm ahead of the base centre"})
    beams: int = field(default=360, metadata={"min": 8, "max": 8192, "help": "bins of each published scan"})
    range_min_m: float = field(default=0.15, metadata={"min": 0.0, "max": 5.0})
    range_max_m: float = field(default=8.0, metadata={
        "min": 0.5, "max": 100.0, "help": "returns beyond are dropped (the thesis robot: 8 m; the A2M8 reaches 12 m)"})
    scan_mode: Literal["standard", "express"] = field(default="standard", metadata={
        "help": "SCAN (5-byte samples) or EXPRESS_SCAN (legacy express capsules)"})
    motor_pwm: int = field(default=660, metadata={"min": 0, "max": 1023, "help": "MOTOR_PWM duty (A2: 660)"})

    def validate(self) -> None:
        _check_pose(self.pose, "pose")
        if self.range_max_m <= self.range_min_m:
            raise ValueError(f"range_max_m ({self.range_max_m}) must exceed range_min_m ({self.range_min_m})")


@dataclass(frozen=True)
class ImuDeviceConfig:
    """The IMU: a WitMotion WT901 on USB serial (0x55 frames), or the simulator's."""

    driver: Literal["auto", "sim", "wt901"] = field(default="auto", metadata={
        "help": "auto: sim in simulation, wt901 on the robot"})
    port: str = field(default="/dev/ttyUSB1", metadata={"help": "serial port (udev: /dev/imu)"})
    baudrate: int = field(default=9600, metadata={"min": 2400, "max": 921_600, "help": "WT901 default: 9600"})
    rotation: tuple[float, ...] = field(default=(0.0, 0.0, 0.0), metadata={
        "help": "the sensor's mounting rotation in the base frame: [roll_rad, pitch_rad, yaw_rad]"})
    bias_s: float = field(default=1.0, metadata={
        "min": 0.0, "max": 30.0, "help": "seconds of standing still at start-up averaged for the gyro bias"})

    def validate(self) -> None:
        _check_pose(self.rotation, "rotation")


@dataclass(frozen=True)
class CameraDeviceConfig:
    """The front camera: anything OpenCV opens (V4L2, a file, an rtsp/http URL), the RealSense D415's colour
    stream, or the simulator's. ``source`` is OpenCV's alone; ``width``, ``height`` and ``fps`` are every
    driver's (a D415 streams colour at 424 x 240, 640 x 480, 848 x 480, 1280 x 720 among others)."""

    driver: Literal["auto", "sim", "opencv", "realsense", "none"] = field(default="auto", metadata={
        "help": "auto: sim in simulation, opencv on the robot; realsense: the D415's colour stream (the camera "
                "devices.depth.serial names, one pipeline with its depth); none: no camera"})
    source: str = field(default="0", metadata={
        "help": "a V4L2 index (0), a device path (/dev/video0), a video file, or an rtsp:// or http:// URL"})
    width: int = field(default=640, metadata={"min": 16, "max": 4096})
    height: int = field(default=480, metadata={"min": 16, "max": 4096})
    fps: float = field(default=10.0, metadata={"min": 0.5, "max": 120.0, "help": "frames per second kept"})


@dataclass(frozen=True)
class DepthDeviceConfig:
    """The depth camera: a RealSense D415 (``realsense``, the ``realsense`` extra), or the simulator's.

    ``auto`` is the simulator's in simulation and none on the robot: naming ``realsense`` says the robot has
    one (and needs pyrealsense2)."""

    driver: Literal["auto", "sim", "realsense", "none"] = field(default="auto", metadata={
        "help": "auto: sim in simulation, none on the robot; realsense: a D415 (pip install 'atemr[realsense]')"})
    pose: tuple[float, ...] = field(default=(0.10, 0.0, 0.85, 0.2094, 0.0), metadata={
        "help": "the optical centre in the base frame and where it looks: [x_m, y_m, z_m, pitch_rad, yaw_rad] "
                "(pitch positive: tilted down); KAY's: on the mast under the tablet, 12 degrees down"})
    serial: str = field(default="", metadata={
        "help": "the D415's serial number (empty: the first one found); camera: realsense reads the same one"})
    width: int = field(default=424, metadata={"min": 16, "max": 1280, "help": "depth stream width (D415: 424)"})
    height: int = field(default=240, metadata={"min": 16, "max": 720, "help": "depth stream height (D415: 240)"})
    fps: int = field(default=15, metadata={"min": 6, "max": 90, "help": "the stream's frame rate (D415: 6..90)"})
    keep_hz: float = field(default=10.0, metadata={"min": 0.5, "max": 90.0, "help": "frames per second kept"})
    range_max_m: float = field(default=3.0, metadata={"min": 0.5, "max": 10.0, "help": "farther is no data"})

    def validate(self) -> None:
        if len(self.pose) != 5 or not all(math.isfinite(v) for v in self.pose):
            raise ValueError(f"pose must be [x_m, y_m, z_m, pitch_rad, yaw_rad], five finite numbers, got "
                             f"{list(self.pose)}")


@dataclass(frozen=True)
class MotorsDeviceConfig:
    """The two RMD-L-7015 drive motors on CAN: real (``rmd``) or the emulators on the robot's bus."""

    driver: Literal["auto", "rmd", "emulated"] = field(default="auto", metadata={
        "help": "auto: emulated in simulation, rmd on the robot"})
    protocol: Literal["v1", "v4"] = field(default="v1", metadata={
        "help": "the motors' CAN protocol: v1 (V1.61, replies on 0x140+id) or v4 (V4.2, replies on 0x240+id)"})


@dataclass(frozen=True)
class SecondaryDeviceConfig:
    """The ESP32 secondary core on CAN: the real board (``esp32``) or its emulator on the robot's bus."""

    driver: Literal["auto", "esp32", "emulated"] = field(default="auto", metadata={
        "help": "auto: emulated in simulation, esp32 on the robot"})


@dataclass(frozen=True)
class DevicesConfig:
    """Every device of the robot and the driver that runs it (see the module docstring)."""

    lidar: LidarDeviceConfig = field(default_factory=LidarDeviceConfig)
    imu: ImuDeviceConfig = field(default_factory=ImuDeviceConfig)
    camera: CameraDeviceConfig = field(default_factory=CameraDeviceConfig)
    depth: DepthDeviceConfig = field(default_factory=DepthDeviceConfig)
    motors: MotorsDeviceConfig = field(default_factory=MotorsDeviceConfig)
    secondary: SecondaryDeviceConfig = field(default_factory=SecondaryDeviceConfig)


#: What ``auto`` means for each device kind: (in simulation, on the robot).
AUTO_DRIVERS = {
    "lidar": ("sim", "rplidar"),
    "imu": ("sim", "wt901"),
    "camera": ("sim", "opencv"),
    "depth": ("sim", "none"),
    "motors": ("emulated", "rmd"),
    "secondary": ("emulated", "esp32"),
}


def resolved_driver(devices: DevicesConfig, kind: str, simulation: bool) -> str:
    """The driver that runs device ``kind``: its ``driver`` setting, with ``auto`` resolved."""
    driver: str = getattr(devices, kind).driver
    if driver == "auto":
        return AUTO_DRIVERS[kind][0 if simulation else 1]
    return driver
