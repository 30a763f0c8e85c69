"""The compiled CDR encoders (`atemr.io.recording.cdr`) write the bytes `mcap-ros2-support` writes, for every type
a recording uses and for messages as the recorder builds them (`ros2_convert`), odd values included: NaN and
infinite ranges, empty arrays, a frame name that is not ASCII, missing fields that take their default."""

from __future__ import annotations

import math

import numpy as np
import pytest
from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic

from atemr.domain.maps import OccupancyMap
from atemr.io.recording import ros2_convert as ros
from atemr.io.recording.cdr import compile_encoder
from atemr.io.recording.ros2_types import MESSAGE_TYPES, full_name, schema_text
from atemr.msgs import CameraMount, DepthImage, ImuSample, LaserScan, Pose2D, Twist


def reference(short: str):  # type: ignore[no-untyped-def]
    return serialize_dynamic(full_name(short), schema_text(short))[full_name(short)]


def samples(rng: np.random.Generator) -> dict[str, list[object]]:
    """Messages of every recorded type, as the recorder builds them, with random values."""
    t = float(rng.uniform(0, 1e5))
    pose = Pose2D(*rng.normal(0, 10, 2), float(rng.uniform(-math.pi, math.pi)))
    cov = rng.normal(0, 0.1, (3, 3))
    ranges = rng.uniform(0.1, 8.0, 360)
    ranges[rng.integers(0, 360, 20)] = np.nan
    ranges[:3] = (np.inf, -np.inf, 0.0)
    scan = LaserScan(t, ranges, -math.pi, 2 * math.pi / 360, 0.15, 8.0, Pose2D(0.1, 0.0, 0.0))
    depth = DepthImage(t, rng.uniform(0, 3, (6, 8)).astype(np.float32), 300.0, 301.0, 4.0, 3.0, 0.3, 3.0,
                       CameraMount(0.1, 0.0, 1.0, 0.3, 0.0))
    grid = OccupancyMap(rng.choice(np.array([-1, 0, 100], dtype=np.int8), (7, 9)), 0.05, pose, name="m")
    twist = Twist(float(rng.normal()), float(rng.normal()))
    transforms = [ros.transform(t, "map", "odom", pose), ros.transform(t, "odom", "base_link", Pose2D())]
    return {
        "sensor_msgs/LaserScan": [ros.scan_msg(scan), {**ros.scan_msg(scan), "ranges": []}],
        "sensor_msgs/Imu": [ros.imu_msg(ImuSample(t, *rng.normal(0, 1, 4)))],
        "sensor_msgs/CompressedImage": [ros.image_msg(t, rng.bytes(50)), ros.image_msg(t, b"")],
        "sensor_msgs/Image": [ros.depth_image_msg(depth)],
        "sensor_msgs/CameraInfo": [ros.depth_info_msg(depth)],
        "nav_msgs/Odometry": [ros.odometry_msg(t, pose, twist, frame="odom_é", child="base_link")],
        "nav_msgs/OccupancyGrid": [ros.grid_msg(t, grid)],
        "nav_msgs/Path": [ros.path_msg(t, rng.normal(0, 5, (4, 2))), ros.path_msg(t, np.zeros((0, 2)))],
        "tf2_msgs/TFMessage": [ros.tf_msg(transforms), ros.tf_msg([])],
        "geometry_msgs/PoseWithCovarianceStamped": [ros.pose_cov_msg(t, pose, cov), ros.pose_cov_msg(t, pose, None),
                                                    {"header": {"frame_id": "map"}}],  # the rest by default
        "geometry_msgs/TwistStamped": [ros.twist_msg(t, twist)],
    }


@pytest.mark.parametrize("short", MESSAGE_TYPES)
def test_the_same_bytes_as_mcap_ros2(short: str) -> None:
    ours, theirs = compile_encoder(short), reference(short)
    for seed in range(5):
        for message in samples(np.random.default_rng(seed))[short]:
            assert ours(message) == theirs(message)


def test_a_recorded_scan_decodes_back_to_its_values() -> None:
    decode = generate_dynamic(full_name("sensor_msgs/LaserScan"), schema_text("sensor_msgs/LaserScan"))
    ranges = np.array([1.0, np.nan, 2.5, np.inf])
    scan = LaserScan(12.25, ranges, -1.0, 0.5, 0.15, 8.0, Pose2D())
    msg = decode[full_name("sensor_msgs/LaserScan")](compile_encoder("sensor_msgs/LaserScan")(ros.scan_msg(scan)))
    back = ros.scan_from(msg, Pose2D())
    assert back.t == 12.25 and np.array_equal(back.ranges_m, ranges.astype(np.float32), equal_nan=True)


def test_a_fixed_array_of_the_wrong_length_is_an_error_naming_it() -> None:
    encode = compile_encoder("geometry_msgs/PoseWithCovarianceStamped")
    with pytest.raises(ValueError, match=r"float64\[36\] needs 36 values, got 3"):
        encode({"header": {"frame_id": "map"}, "pose": {"covariance": [0.0, 1.0, 2.0]}})


def test_defaults_and_an_empty_message_as_mcap_ros2_writes_them(monkeypatch: pytest.MonkeyPatch) -> None:
    """Definitions beyond the recording's own: defaults of every kind for missing fields, and an empty message
    (one uint8 in ROS 2's IDL)."""
    import atemr.io.recording.cdr as cdr

    fields = {"test_msgs/Flags": "bool on true\nbool off false\nint32 n -7\nuint8 u 3\nfloat32 f 1.5\n"
                                 "string s hello\ntest_msgs/Empty e\nstring[] names\nint16[2] pair",
              "test_msgs/Empty": ""}
    monkeypatch.setattr(cdr, "field_lines", lambda short: fields[short].splitlines())
    schema = fields["test_msgs/Flags"] + "\n" + "=" * 80 + "\nMSG: test_msgs/Empty\n\n"
    theirs = serialize_dynamic("test_msgs/msg/Flags", schema)["test_msgs/msg/Flags"]
    ours = compile_encoder("test_msgs/Flags")
    for message in ({}, {"on": False, "n": 5, "s": "é", "names": ["a", "bc"], "pair": [1, -2]}):
        assert ours(message) == theirs(message), message
