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


def random_definitions(rng: np.random.Generator) -> dict[str, str]:
    """A top type and two nested types of random fields of every kind the generator treats apart: each
    primitive, strings, sequences, short and long fixed arrays (bytes among them), nested messages and arrays
    of them, in random order, so fixed-size runs meet variable-length fields at every alignment."""
    primitives = ["bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
                  "float32", "float64"]

    def fields(count: int, nested: list[str]) -> str:
        lines = []
        for k in range(count):
            kind = primitives[rng.integers(len(primitives))]
            shape = rng.integers(8)
            if shape == 0:
                lines.append(f"string f{k}")
            elif shape == 1:
                lines.append(f"{kind}[] f{k}")
            elif shape == 2:
                lines.append(f"{kind}[{rng.choice([1, 3, 9, 70])}] f{k}")
            elif shape == 3 and nested:
                lines.append(f"{nested[rng.integers(len(nested))]}{rng.choice(['', '[]', '[2]'])} f{k}")
            elif shape == 4:
                lines.append(f"string[] f{k}")
            else:
                lines.append(f"{kind} f{k}")
        return "\n".join(lines)

    return {"rnd/Leaf": fields(5, []), "rnd/Mid": fields(7, ["rnd/Leaf"]),
            "rnd/Top": fields(14, ["rnd/Leaf", "rnd/Mid"])}


def random_message(short: str, defs: dict[str, str], rng: np.random.Generator) -> dict[str, object]:
    """Values for ``short``'s fields, about one in six left out (its default)."""
    ranges = {"bool": (0, 2), "byte": (0, 256), "char": (-128, 128), "int8": (-128, 128), "uint8": (0, 256),
              "int16": (-2**15, 2**15), "uint16": (0, 2**16), "int32": (-2**31, 2**31), "uint32": (0, 2**32),
              "int64": (-2**62, 2**62), "uint64": (0, 2**63)}

    def one(kind: str) -> object:
        if kind == "string":
            return "".join(rng.choice(list("abcé")) for _ in range(rng.integers(0, 6)))
        if kind.startswith("rnd/"):
            return random_message(kind, defs, rng)
        if kind in ("float32", "float64"):
            return float(rng.integers(-1000, 1000)) / 8.0  # exact in float32
        low, high = ranges[kind]
        value = int(rng.integers(low, high, dtype=np.int64 if high <= 2**62 else np.uint64))
        return bool(value) if kind == "bool" else value

    out: dict[str, object] = {}
    for line in defs[short].splitlines():
        spec, name = line.split()
        if rng.integers(6) == 0:
            continue
        if "[" not in spec:
            out[name] = one(spec)
            continue
        kind, bound = spec[:-1].split("[")
        out[name] = [one(kind) for _ in range(int(bound) if bound else rng.integers(0, 4))]
    return out


@pytest.mark.parametrize("seed", range(40))
def test_random_definitions_give_mcap_ros2s_bytes(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    import atemr.io.recording.cdr as cdr

    rng = np.random.default_rng(seed)
    defs = random_definitions(rng)
    monkeypatch.setattr(cdr, "field_lines", lambda short: defs[short].splitlines())
    schema = defs["rnd/Top"] + "".join(f"\n{'=' * 80}\nMSG: {name}\n{defs[name]}" for name in ("rnd/Mid", "rnd/Leaf"))
    theirs = serialize_dynamic("rnd/msg/Top", schema)["rnd/msg/Top"]
    ours = compile_encoder("rnd/Top")
    for _ in range(20):
        message = random_message("rnd/Top", defs, rng)
        assert ours(message) == theirs(message), message
