"""The robot's own messages (`atemr.msgs`, maps, poses) as ROS 2 message dicts and back; pure, no I/O.

A dict here is what `mcap-ros2-support` encodes to CDR (field names as in the ROS 2 definitions of
`atemr.io.recording.ros2_types`); the ``*_from`` functions take what its decoder returns (objects with the
same attribute names). Stamps are robot time (the simulated clock in simulation, the monotonic clock on the
robot), the same time as the MCAP ``log_time``; frames follow REP 105: ``map`` → ``odom`` → ``base_link`` →
``laser`` / ``imu_link`` / ``camera``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from atemr.domain.maps import OccupancyMap
from atemr.msgs import CameraMount, DepthImage, ImuSample, LaserScan, Pose2D, Twist

Msg = dict[str, Any]

MAP_FRAME, ODOM_FRAME, BASE_FRAME = "map", "odom", "base_link"
LASER_FRAME, IMU_FRAME, CAMERA_FRAME = "laser", "imu_link", "camera"
#: The depth camera's optical frame (x right, y down, z forward, as the RealSense ROS driver names it).
DEPTH_FRAME = "camera_depth_optical_frame"
#: The depth image's unit: millimetres in 16 bits, what RealSense gives and ROS depth tools read (16UC1).
DEPTH_MM_PER_M = 1000.0

_NS = 1_000_000_000


def nanoseconds(t: float) -> int:
    """Robot time in seconds as integer nanoseconds (an MCAP ``log_time``); times before 0 are 0."""
    return max(0, round(t * _NS))


def stamp(t: float) -> Msg:
    ns = nanoseconds(t)
    return {"sec": ns // _NS, "nanosec": ns % _NS}


def seconds(value: Any) -> float:
    """A decoded ``builtin_interfaces/Time`` as seconds."""
    return float(value.sec) + float(value.nanosec) / _NS


def header(t: float, frame: str) -> Msg:
    return {"stamp": stamp(t), "frame_id": frame}


def quaternion(yaw_rad: float) -> Msg:
    """A rotation about z (the robot lives in the plane)."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw_rad / 2.0), "w": math.cos(yaw_rad / 2.0)}


def yaw_of(q: Any) -> float:
    """The heading of a decoded quaternion (its rotation about z)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def pose(p: Pose2D) -> Msg:
    return {"position": {"x": p.x_m, "y": p.y_m, "z": 0.0}, "orientation": quaternion(p.yaw_rad)}


def pose_from(msg: Any) -> Pose2D:
    return Pose2D(float(msg.position.x), float(msg.position.y), yaw_of(msg.orientation))


#: Where the 3×3 (x, y, yaw) covariance's entries go in ROS's row-major 6×6, row by row.
_COV6_INDEX = (0, 1, 5, 6, 7, 11, 30, 31, 35)


def covariance6(cov3: NDArray[np.float64] | None) -> list[float]:
    """A 3×3 (x, y, yaw) covariance as ROS's row-major 6×6 (x, y, z, roll, pitch, yaw); z, roll and pitch 0."""
    out = [0.0] * 36
    if cov3 is not None:
        for index, value in zip(_COV6_INDEX, np.asarray(cov3, dtype=np.float64)[:3, :3].ravel().tolist(),
                                strict=True):
            out[index] = value
    return out


def covariance3(cov6: Any) -> NDArray[np.float64]:
    index = np.array([0, 1, 5])
    return np.asarray(cov6, dtype=np.float64).reshape(6, 6)[np.ix_(index, index)]


# -- sensors ------------------------------------------------------------------------------------------------
def scan_msg(scan: LaserScan, scan_time_s: float = 0.1) -> Msg:
    """A scan in the ``laser`` frame (where it is mounted is the ``base_link`` → ``laser`` transform)."""
    n = len(scan.ranges_m)
    return {"header": header(scan.t, LASER_FRAME), "angle_min": scan.angle_min_rad,
            "angle_max": scan.angle_min_rad + scan.angle_increment_rad * max(n - 1, 0),
            "angle_increment": scan.angle_increment_rad, "time_increment": 0.0, "scan_time": scan_time_s,
            "range_min": scan.range_min_m, "range_max": scan.range_max_m,
            "ranges": np.asarray(scan.ranges_m, dtype=np.float64).tolist(), "intensities": []}


def scan_from(msg: Any, sensor_pose: Pose2D) -> LaserScan:
    """A decoded LaserScan as the robot's, mounted at ``sensor_pose`` (from the static transforms)."""
    return LaserScan(seconds(msg.header.stamp), np.asarray(msg.ranges, dtype=np.float64), float(msg.angle_min),
                     float(msg.angle_increment), float(msg.range_min), float(msg.range_max), sensor_pose)


def imu_msg(sample: ImuSample) -> Msg:
    """The yaw rate and accelerations; no orientation estimate (covariance[0] = -1, as REP 145 says)."""
    return {"header": header(sample.t, IMU_FRAME), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            "orientation_covariance": [-1.0] + [0.0] * 8,
            "angular_velocity": {"x": 0.0, "y": 0.0, "z": sample.yaw_rate_radps},
            "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": {"x": sample.accel_x_mps2, "y": sample.accel_y_mps2, "z": sample.accel_z_mps2},
            "linear_acceleration_covariance": [0.0] * 9}


def imu_from(msg: Any) -> ImuSample:
    a = msg.linear_acceleration
    return ImuSample(seconds(msg.header.stamp), float(msg.angular_velocity.z), float(a.x), float(a.y), float(a.z))


def image_msg(t: float, jpeg: bytes) -> Msg:
    return {"header": header(t, CAMERA_FRAME), "format": "jpeg", "data": jpeg}


def depth_image_msg(frame: DepthImage) -> Msg:
    """A depth frame as ``sensor_msgs/Image`` ``16UC1`` in millimetres (0: no data), as the RealSense ROS driver
    publishes it, so Foxglove and ROS depth tools show and project it as they are."""
    mm = np.clip(np.rint(frame.depth_m * DEPTH_MM_PER_M), 0, np.iinfo(np.uint16).max).astype("<u2")
    height, width = mm.shape
    return {"header": header(frame.t, DEPTH_FRAME), "height": height, "width": width, "encoding": "16UC1",
            "is_bigendian": 0, "step": 2 * width, "data": mm.tobytes()}


def depth_info_msg(frame: DepthImage) -> Msg:
    """The depth frame's pinhole intrinsics as ``sensor_msgs/CameraInfo`` (no distortion: the D415's depth
    stream comes rectified), which Foxglove uses to turn the image into a point cloud."""
    height, width = frame.depth_m.shape
    k = [frame.fx, 0.0, frame.cx, 0.0, frame.fy, frame.cy, 0.0, 0.0, 1.0]
    return {"header": header(frame.t, DEPTH_FRAME), "height": height, "width": width, "distortion_model": "plumb_bob",
            "d": [0.0] * 5, "k": k, "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "p": [frame.fx, 0.0, frame.cx, 0.0, 0.0, frame.fy, frame.cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}


def depth_from(image: Any, info: Any) -> DepthImage:
    """A decoded ``16UC1`` image and its camera info back as the `DepthImage` the robot's layer reads (metres;
    the mount is the static transform's, not carried here)."""
    if image.encoding != "16UC1":
        raise ValueError(f"a depth image must be 16UC1, got {image.encoding!r}")
    mm = np.frombuffer(bytes(image.data), dtype=">u2" if image.is_bigendian else "<u2")
    depth = (mm.reshape(int(image.height), int(image.width)) / DEPTH_MM_PER_M).astype(np.float32)
    k = list(info.k)
    valid = depth[depth > 0]
    return DepthImage(seconds(image.header.stamp), depth, float(k[0]), float(k[4]), float(k[2]), float(k[5]),
                      float(valid.min()) if valid.size else 0.0, float(valid.max()) if valid.size else 0.0)


def optical_transform(t: float, parent: str, mount: CameraMount) -> Msg:
    """Where a camera's optical frame (x right, y down, z forward) sits on the base: the mount's position, its
    yaw and downward pitch, then the fixed turn from a body frame to an optical one."""
    from scipy.spatial.transform import Rotation

    body = Rotation.from_euler("ZY", [mount.yaw_rad, mount.pitch_rad])
    x, y, z, w = (body * Rotation.from_quat([-0.5, 0.5, -0.5, 0.5])).as_quat()
    return {"header": header(t, parent), "child_frame_id": DEPTH_FRAME,
            "transform": {"translation": {"x": mount.x_m, "y": mount.y_m, "z": mount.z_m},
                          "rotation": {"x": float(x), "y": float(y), "z": float(z), "w": float(w)}}}


# -- poses and motion ----------------------------------------------------------------------------------------
def odometry_msg(t: float, p: Pose2D, twist: Twist, *, frame: str = ODOM_FRAME, child: str = BASE_FRAME,
                 pose_cov: NDArray[np.float64] | None = None) -> Msg:
    """``p`` in ``frame`` and the base's velocity in ``child`` (forward and turn rate)."""
    return {"header": header(t, frame), "child_frame_id": child,
            "pose": {"pose": pose(p), "covariance": covariance6(pose_cov)},
            "twist": {"twist": {"linear": {"x": twist.linear_mps, "y": 0.0, "z": 0.0},
                                "angular": {"x": 0.0, "y": 0.0, "z": twist.angular_radps}},
                      "covariance": [0.0] * 36}}


def twist_msg(t: float, twist: Twist, frame: str = BASE_FRAME) -> Msg:
    """A TwistStamped: the base's velocity (forward, turn rate) in ``frame``."""
    return {"header": header(t, frame), "twist": {"linear": {"x": twist.linear_mps, "y": 0.0, "z": 0.0},
                                                  "angular": {"x": 0.0, "y": 0.0, "z": twist.angular_radps}}}


def twist_from(msg: Any) -> Twist:
    """The velocity of a decoded TwistStamped."""
    return Twist(float(msg.twist.linear.x), float(msg.twist.angular.z))


def pose_cov_msg(t: float, p: Pose2D, cov3: NDArray[np.float64] | None) -> Msg:
    """A PoseWithCovarianceStamped in ``map``: the localized pose."""
    return {"header": header(t, MAP_FRAME), "pose": {"pose": pose(p), "covariance": covariance6(cov3)}}


def transform(t: float, parent: str, child: str, p: Pose2D) -> Msg:
    return {"header": header(t, parent), "child_frame_id": child,
            "transform": {"translation": {"x": p.x_m, "y": p.y_m, "z": 0.0}, "rotation": quaternion(p.yaw_rad)}}


def tf_msg(transforms: list[Msg]) -> Msg:
    return {"transforms": transforms}


def transforms_from(msg: Any) -> dict[tuple[str, str], Pose2D]:
    """A decoded TFMessage as ``{(parent, child): pose of child in parent}``."""
    out = {}
    for tr in msg.transforms:
        move = tr.transform
        out[(str(tr.header.frame_id), str(tr.child_frame_id))] = Pose2D(float(move.translation.x),
                                                                        float(move.translation.y),
                                                                        yaw_of(move.rotation))
    return out


def path_msg(t: float, points: NDArray[np.float64]) -> Msg:
    """A planned path (N×2 points in ``map``) as poses without heading."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return {"header": header(t, MAP_FRAME),
            "poses": [{"header": header(t, MAP_FRAME), "pose": pose(Pose2D(float(x), float(y)))} for x, y in pts]}


# -- maps -----------------------------------------------------------------------------------------------------
def grid_msg(t: float, grid: OccupancyMap) -> Msg:
    """The map as an OccupancyGrid: same cell values and layout (row 0 at the origin, row-major)."""
    height, width = grid.data.shape
    return {"header": header(t, MAP_FRAME),
            "info": {"map_load_time": stamp(t), "resolution": grid.resolution_m, "width": width, "height": height,
                     "origin": pose(grid.origin)},
            "data": grid.data.ravel().tolist()}


def grid_from(msg: Any, name: str = "map") -> OccupancyMap:
    """A decoded OccupancyGrid as a map (`ConfigError` when its size does not match its data)."""
    info = msg.info
    data = np.asarray(msg.data, dtype=np.int8)
    if data.size != int(info.width) * int(info.height):
        from atemr.errors import ConfigError

        raise ConfigError(f"map '{name}': {data.size} cells for {info.width} x {info.height}")
    return OccupancyMap(data.reshape(int(info.height), int(info.width)), float(info.resolution),
                        pose_from(info.origin), name=name)


__all__ = [
    "BASE_FRAME",
    "CAMERA_FRAME",
    "DEPTH_FRAME",
    "DEPTH_MM_PER_M",
    "IMU_FRAME",
    "LASER_FRAME",
    "MAP_FRAME",
    "ODOM_FRAME",
    "covariance3",
    "covariance6",
    "depth_from",
    "depth_image_msg",
    "depth_info_msg",
    "grid_from",
    "grid_msg",
    "header",
    "image_msg",
    "imu_from",
    "imu_msg",
    "nanoseconds",
    "odometry_msg",
    "optical_transform",
    "path_msg",
    "pose_cov_msg",
    "pose_from",
    "scan_from",
    "scan_msg",
    "seconds",
    "stamp",
    "tf_msg",
    "transform",
    "transforms_from",
    "twist_from",
    "twist_msg",
    "yaw_of",
]
