"""The ROS 2 message definitions a recording uses, as rosbag2 stores them in an MCAP ``ros2msg`` schema.

A schema is the message's own definition followed by each type it uses, every one after a line of ``=`` and
``MSG: package/Type``, so a file decodes without ROS installed (Foxglove, ``mcap-ros2-support``, ``ros2 bag
play``). The field lists are those of the ROS 2 interfaces (``std_msgs``, ``geometry_msgs``, ``sensor_msgs``,
``nav_msgs``, ``tf2_msgs``), without their comments.
"""

from __future__ import annotations

_SEPARATOR = "=" * 80

#: Each type's own fields, by short name (``package/Type``).
_FIELDS: dict[str, str] = {
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose",
    "geometry_msgs/PoseWithCovariance": "geometry_msgs/Pose pose\nfloat64[36] covariance",
    "geometry_msgs/PoseWithCovarianceStamped": "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose",
    "geometry_msgs/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\ngeometry_msgs/Twist twist",
    "geometry_msgs/TwistWithCovariance": "geometry_msgs/Twist twist\nfloat64[36] covariance",
    "geometry_msgs/Transform": "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\n"
                                      "geometry_msgs/Transform transform",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "sensor_msgs/LaserScan": "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n"
                             "float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n"
                             "float32[] ranges\nfloat32[] intensities",
    "sensor_msgs/Imu": "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
                       "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
                       "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
                       "float64[9] linear_acceleration_covariance",
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "sensor_msgs/Image": "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n"
                         "uint32 step\nuint8[] data",
    "sensor_msgs/RegionOfInterest": "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify",
    "sensor_msgs/CameraInfo": "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
                              "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
                              "uint32 binning_y\nsensor_msgs/RegionOfInterest roi",
    "nav_msgs/Odometry": "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
                         "geometry_msgs/TwistWithCovariance twist",
    "nav_msgs/MapMetaData": "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\n"
                            "uint32 height\ngeometry_msgs/Pose origin",
    "nav_msgs/OccupancyGrid": "std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data",
    "nav_msgs/Path": "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses",
}


def _uses(short: str) -> list[str]:
    """The message types ``short``'s fields name (builtin_interfaces types are known to every decoder)."""
    out = []
    for line in _FIELDS[short].splitlines():
        kind = line.split()[0].split("[")[0]
        if "/" in kind and not kind.startswith("builtin_interfaces/"):
            out.append(kind)
    return out


def _closure(short: str) -> list[str]:
    """Every type ``short`` depends on, each once, in first-use order."""
    seen: list[str] = []
    stack = list(reversed(_uses(short)))
    while stack:
        name = stack.pop()
        if name in seen:
            continue
        seen.append(name)
        stack.extend(reversed(_uses(name)))
    return seen


def field_lines(short: str) -> list[str]:
    """The field lines of ``short``'s own definition (``type name [default]``)."""
    return _FIELDS[short].splitlines()


def short_name(full: str) -> str:
    """``sensor_msgs/msg/LaserScan`` → ``sensor_msgs/LaserScan``."""
    package, _, name = full.split("/")
    return f"{package}/{name}"


def full_name(short: str) -> str:
    """``sensor_msgs/LaserScan`` → ``sensor_msgs/msg/LaserScan``, the name ROS 2 schemas carry."""
    package, name = short.split("/")
    return f"{package}/msg/{name}"


def schema_text(short: str) -> str:
    """The ``ros2msg`` schema of ``short``: its fields, then each dependency's (see the module docstring)."""
    parts = [_FIELDS[short]]
    for dep in _closure(short):
        parts.append(f"{_SEPARATOR}\nMSG: {dep}\n{_FIELDS[dep]}")
    return "\n".join(parts) + "\n"


#: The types a recording's ROS 2 channels carry.
MESSAGE_TYPES = ("sensor_msgs/LaserScan", "sensor_msgs/Imu", "sensor_msgs/CompressedImage", "sensor_msgs/Image",
                 "sensor_msgs/CameraInfo", "nav_msgs/Odometry",
                 "nav_msgs/OccupancyGrid", "nav_msgs/Path", "tf2_msgs/TFMessage",
                 "geometry_msgs/PoseWithCovarianceStamped", "geometry_msgs/TwistStamped")

__all__ = ["MESSAGE_TYPES", "field_lines", "full_name", "schema_text", "short_name"]
