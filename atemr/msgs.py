"""The data that flows between parts: plain frozen dataclasses, SI units in the field names.

Sensors (simulated or real) produce these, skills consume and produce them, the agent and the dashboard
read them. Arrays are numpy; angles are radians, counter-clockwise positive; the base frame has x
forward and y to the left (REP 103).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Pose2D:
    """A pose in the plane: position in metres, heading in radians."""

    x_m: float = 0.0
    y_m: float = 0.0
    yaw_rad: float = 0.0

    def distance_to(self, other: Pose2D) -> float:
        return math.hypot(other.x_m - self.x_m, other.y_m - self.y_m)


@dataclass(frozen=True)
class Twist:
    """A velocity command or measurement of the base: forward speed and turn rate."""

    linear_mps: float = 0.0
    angular_radps: float = 0.0

    @property
    def is_zero(self) -> bool:
        return self.linear_mps == 0.0 and self.angular_radps == 0.0


ZERO_TWIST = Twist()


@dataclass(frozen=True)
class WheelSpeeds:
    """Wheel angular speeds in rad/s; positive drives the robot forward on both sides."""

    left_radps: float = 0.0
    right_radps: float = 0.0


@dataclass(frozen=True)
class LaserScan:
    """One lidar revolution, as ROS's sensor_msgs/LaserScan.

    ``ranges_m[i]`` is measured at ``angle_min_rad + i * angle_increment_rad`` in the sensor frame.
    Invalid returns are NaN, 0, +inf or outside [range_min_m, range_max_m]; -inf means "closer than
    the minimum range". ``sensor_pose`` is the sensor's pose in the base frame.
    """

    t: float
    ranges_m: FloatArray
    angle_min_rad: float
    angle_increment_rad: float
    range_min_m: float
    range_max_m: float
    sensor_pose: Pose2D = field(default_factory=Pose2D)

    @property
    def angles_rad(self) -> FloatArray:
        """The beam angles in the sensor frame."""
        return self.angle_min_rad + self.angle_increment_rad * np.arange(len(self.ranges_m), dtype=np.float64)


@dataclass(frozen=True)
class ImuSample:
    """Yaw rate (rad/s) and linear acceleration in the base frame (m/s²); ``accel_z_mps2`` is what the
    accelerometer reads upwards, +g on a level floor (the simulator does not model tilt)."""

    t: float
    yaw_rate_radps: float
    accel_x_mps2: float
    accel_y_mps2: float
    accel_z_mps2: float = 9.80665


@dataclass(frozen=True)
class CliffReadings:
    """The three IR cliff sensors, distance to the floor in metres (inf: nothing within range)."""

    t: float
    front_left_m: float
    front_right_m: float
    rear_m: float


@dataclass(frozen=True)
class CameraMount:
    """Where a camera sits on the robot: its optical centre in the base frame (metres, z up from the floor)
    and where it looks: ``pitch_rad`` positive tilts it down (REP 103), ``yaw_rad`` turns it left."""

    x_m: float = 0.0
    y_m: float = 0.0
    z_m: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0


@dataclass(frozen=True)
class DepthImage:
    """One depth frame, as a RealSense gives it: ``depth_m[v, u]`` is the distance along the optical axis
    (z-depth, not the range along the ray) of the surface seen by pixel (u, v), 0 where there is no data.

    The pinhole intrinsics (``fx``, ``fy``, ``cx``, ``cy``, pixels; the optical frame has x right, y down,
    z forward) turn a pixel back into a 3-D point; ``mount`` places the camera on the robot. Readings outside
    ``range_min_m``..``range_max_m`` are already 0.
    """

    t: float
    depth_m: NDArray[np.float32]
    fx: float
    fy: float
    cx: float
    cy: float
    range_min_m: float
    range_max_m: float
    mount: CameraMount = field(default_factory=CameraMount)

    @property
    def width(self) -> int:
        return int(self.depth_m.shape[1])

    @property
    def height(self) -> int:
        return int(self.depth_m.shape[0])
