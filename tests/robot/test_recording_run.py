"""A run of the whole simulated robot records every channel of issue 23 to MCAP: the `mcap` reader lists each
with its schema, `mcap-ros2-support` decodes the scans, odometry and transforms back to the values the robot's
parts produced, and a file cut mid-chunk still reads up to the cut."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from atemr.config import load_config
from atemr.errors import ConfigError
from atemr.io.recording.agent_trace import read_agent_trace
from atemr.io.recording.mcap_reader import RecordingReader
from atemr.io.recording.ros2_convert import DEPTH_FRAME, depth_from, seconds, yaw_of
from atemr.io.recording.topics import TOPICS
from atemr.msgs import DepthImage, LaserScan, Pose2D, Twist, WheelSpeeds
from atemr.robot.core import Robot
from atemr.robot.headless import build_headless_robot
from atemr.robot.replay import Replay, replay_slam
from atemr.skills.slam import SlamParams


@dataclass
class Run:
    path: Path
    robot: Robot
    scans: list[LaserScan] = field(default_factory=list)
    depths: list[DepthImage] = field(default_factory=list)
    wheels: list[tuple[float, Twist]] = field(default_factory=list)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    """Eight robot seconds: idle, then a goal (so a global path exists), an event, the camera at 2 fps."""
    folder = tmp_path_factory.mktemp("recorded")
    config = load_config(environ={}, overrides={"data_dir": str(folder), "trace.file": str(folder / "run.mcap"),
                                                "trace.camera_hz": 2.0, "sim.seed": 3})
    robot = build_headless_robot(config)
    out = Run(folder / "run.mcap", robot)
    drive = robot.parts.localization.drive

    def on_wheels(t: float, wheels: WheelSpeeds) -> None:
        out.wheels.append((t, drive.measured(wheels)))

    robot.parts.devices.lidar.subscribe(out.scans.append)
    assert robot.parts.devices.depth is not None, "the simulated robot has its D415"
    robot.parts.devices.depth.subscribe(out.depths.append)
    robot.parts.wheels.subscribe(on_wheels)
    agent = robot.parts.agent
    with robot:
        robot.run(until=4.0)
        agent.submit("set_auto")
        robot.run(until=4.5)
        agent.submit("goal", goal=Pose2D(3.6, 2.6, 0.0))
        robot.event("test", "a goal was sent")
        robot.run(until=8.0)
    return out


def test_the_mcap_reader_lists_every_channel_with_its_schema(run: Run) -> None:
    with run.path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    found = {c.topic: (summary.schemas[c.schema_id].name, summary.schemas[c.schema_id].encoding, c.message_encoding)
             for c in summary.channels.values()}
    assert found == {t.name: (t.schema_name, t.schema_encoding, t.message_encoding) for t in TOPICS.values()}
    assert summary.statistics is not None and summary.statistics.message_count > 1500
    assert found["/scan"] == ("sensor_msgs/msg/LaserScan", "ros2msg", "cdr")


def decoded(path: Path, topic: str) -> list:
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(m.log_time, ros) for _, _, m, ros in reader.iter_decoded_messages(topics=[topic])]


def test_scans_decode_to_what_the_lidar_gave(run: Run) -> None:
    got = decoded(run.path, "/scan")
    assert len(got) == len(run.scans) > 70
    for (log_time, msg), scan in zip(got, run.scans, strict=True):
        assert log_time == round(scan.t * 1e9) and seconds(msg.header.stamp) == pytest.approx(scan.t)
        assert msg.header.frame_id == "laser"
        assert msg.angle_min == pytest.approx(scan.angle_min_rad, abs=1e-6)
        assert msg.angle_increment == pytest.approx(scan.angle_increment_rad, rel=1e-6)
        np.testing.assert_array_equal(np.asarray(msg.ranges, np.float32), scan.ranges_m.astype(np.float32))
    laser = decoded(run.path, "/tf_static")[0][1].transforms[0]
    assert (laser.header.frame_id, laser.child_frame_id) == ("base_link", "laser")
    assert laser.transform.translation.x == pytest.approx(run.scans[0].sensor_pose.x_m)


def test_wheel_odometry_decodes_to_what_localization_received(run: Run) -> None:
    got = decoded(run.path, "/wheel_odom")
    assert len(got) == len(run.wheels) > 300
    for (log_time, msg), (t, twist) in zip(got, run.wheels, strict=True):
        assert log_time == round(t * 1e9) and msg.header.frame_id == "base_link"
        assert (msg.twist.linear.x, msg.twist.angular.z) == (twist.linear_mps, twist.angular_radps)
    assert any(abs(t.linear_mps) > 0.05 for _, t in run.wheels), "the robot drove to its goal"


def test_transforms_chain_map_odom_base_link_to_the_localized_pose(run: Run) -> None:
    poses = {t: msg.pose.pose for t, msg in decoded(run.path, "/pose")}
    checked = 0
    for t, msg in decoded(run.path, "/tf"):
        moves = {(tr.header.frame_id, tr.child_frame_id): tr.transform for tr in msg.transforms}
        assert ("odom", "base_link") in moves
        if t not in poses or ("map", "odom") not in moves:
            continue
        mo, ob = moves[("map", "odom")], moves[("odom", "base_link")]
        yaw = yaw_of(mo.rotation)
        x = mo.translation.x + math.cos(yaw) * ob.translation.x - math.sin(yaw) * ob.translation.y
        y = mo.translation.y + math.sin(yaw) * ob.translation.x + math.cos(yaw) * ob.translation.y
        assert (x, y) == pytest.approx((poses[t].position.x, poses[t].position.y), abs=1e-9)
        checked += 1
    assert checked > 50
    plan = decoded(run.path, "/plan")
    assert any(len(msg.poses) > 2 for _, msg in plan), "the global path to the goal"
    last = plan[-1][1]
    if last.poses:
        assert last.poses[-1].pose.position.x == pytest.approx(3.6, abs=0.1)


def test_the_agent_health_events_and_camera_are_recorded(run: Run) -> None:
    contents = read_agent_trace(run.path)
    kinds = {r["k"] for r in contents.records}
    assert {"head", "snap", "tr", "tree", "st", "bb", "pose"} <= kinds and not contents.warnings
    reader = RecordingReader(run.path)
    by_topic: dict[str, list] = {}
    for message in reader.messages({"/health", "/events", "/agent/state", "/camera/image/compressed", "/can/frames"}):
        by_topic.setdefault(message.topic, []).append(reader.decode(message))
    assert {"test"} <= {e["kind"] for e in by_topic["/events"]}
    assert by_topic["/health"][-1]["components"]["lidar"]["ok"] is True
    assert [s["state"] for s in by_topic["/agent/state"]][-1] == "EXEC"
    frames = by_topic["/camera/image/compressed"]
    assert 12 <= len(frames) <= 17 and bytes(frames[0].data[:2]) == b"\xff\xd8"  # JPEG at 2 fps over 8 s
    assert len({f["id"] for m in by_topic["/can/frames"] for f in m["frames"]}) >= 4  # motors, secondary core


def test_the_gyro_bias_learned_while_standing_is_recorded_and_is_the_simulated_gyros(run: Run) -> None:
    """The robot stood for four seconds, then drove to its goal: the recording shows the bias the odometry learned
    while it stood (the simulated gyro's own, within 0.0002 rad/s), held while it drove."""
    reader = RecordingReader(run.path)
    got = [reader.decode(m) for m in reader.messages({"/odom/gyro_bias"})]
    assert 7 <= len(got) <= 9  # once a second over 8 s
    assert any(g["standing"] for g in got) and not got[-1]["standing"], got
    assert run.robot.parts.sim is not None
    truth = run.robot.parts.sim.imu.gyro_bias_radps
    assert got[-1]["bias_radps"] == run.robot.parts.localization.odometry.gyro_bias_radps
    assert got[-1]["bias_radps"] == pytest.approx(truth, abs=2e-4), (got[-1], truth)
    assert abs(truth) > 5e-4, "a gyro with a bias to learn"


def test_depth_frames_decode_to_what_the_depth_camera_gave_and_sit_on_the_mast(run: Run) -> None:
    """Issues 23 and 24: the D415's frames as ROS 2 depth images (16UC1 millimetres) with their camera info at
    trace.depth_hz, in an optical frame the static transforms put where the camera is mounted, looking ahead
    and down: what Foxglove needs to draw them as a point cloud in the robot's frame."""
    from scipy.spatial.transform import Rotation

    with open(run.path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        got: dict[str, list] = {}
        for _, channel, _, msg in reader.iter_decoded_messages(
                topics=["/camera/depth/image_rect_raw", "/camera/depth/camera_info", "/tf_static"]):
            got.setdefault(channel.topic, []).append(msg)
    images, infos = got["/camera/depth/image_rect_raw"], got["/camera/depth/camera_info"]
    assert 6 <= len(images) == len(infos) <= 10  # 1 Hz over 8 s (the default trace.depth_hz)
    given = {round(d.t, 6): d for d in run.depths}
    for image, info in zip(images, infos, strict=True):
        assert image.encoding == "16UC1" and image.header.frame_id == DEPTH_FRAME
        frame = given[round(seconds(image.header.stamp), 6)]
        back = depth_from(image, info)
        assert back.depth_m.shape == frame.depth_m.shape == (240, 424)
        assert np.abs(back.depth_m - frame.depth_m).max() <= 0.0005 + 1e-6  # to the millimetre
        assert (back.fx, back.fy, back.cx, back.cy) == pytest.approx((frame.fx, frame.fy, frame.cx, frame.cy))
    mount = run.depths[-1].mount
    placed = {(t.header.frame_id, t.child_frame_id): t.transform for m in got["/tf_static"] for t in m.transforms}
    move = placed[("base_link", DEPTH_FRAME)]
    assert (move.translation.x, move.translation.y, move.translation.z) == pytest.approx(
        (mount.x_m, mount.y_m, mount.z_m))
    q = move.rotation
    ahead = Rotation.from_quat([q.x, q.y, q.z, q.w]).apply([0.0, 0.0, 1.0])  # the optical axis, in base_link
    assert ahead == pytest.approx([math.cos(mount.pitch_rad), 0.0, -math.sin(mount.pitch_rad)], abs=1e-9)
    right = Rotation.from_quat([q.x, q.y, q.z, q.w]).apply([1.0, 0.0, 0.0])  # image x: the robot's right
    assert right == pytest.approx([0.0, -1.0, 0.0], abs=1e-9)


def test_a_recording_cut_mid_chunk_reads_up_to_the_cut(run: Run, tmp_path: Path) -> None:
    data = run.path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    reader = RecordingReader(cut)
    scans = [reader.decode(m) for m in reader.messages({"/scan"})]
    assert 0.3 * len(run.scans) < len(scans) < len(run.scans)
    assert [seconds(s.header.stamp) for s in scans] == pytest.approx([s.t for s in run.scans[: len(scans)]])
    assert len(reader.warnings) == 1 and "cut.mcap" in reader.warnings[0]
    trace = read_agent_trace(cut)
    assert trace.records[0]["k"] == "head" and trace.warnings


def test_localization_replayed_on_the_map_follows_the_recorded_and_the_true_pose(run: Run) -> None:
    """``atemr replay --localize``: odometry and AMCL re-run on the studio map from the recording alone."""
    grid = run.robot.parts.maps.active
    assert grid is not None
    result = Replay(run.path, grid=grid, seed=1).run()
    assert result.scans == len(run.scans) and result.localized_scans > 0.9 * result.scans
    recorded, truth = result.against_recorded.report(), result.against_truth.report()
    assert recorded["samples"] > 70 and recorded["rmse_m"] < 0.1
    assert truth["samples"] > 70 and truth["rmse_m"] < 0.1 and truth["max_m"] < 0.25


def test_replay_refuses_what_it_cannot_use(run: Run, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"run\.mcap: the recording holds no mapping session"):
        replay_slam(run.path, SlamParams())
    result = replay_slam(run.path, SlamParams(), all_scans=True)
    assert result.grid is not None and result.grid.occupied.sum() > 100
    notes = tmp_path / "notes.mcap"
    notes.write_text("not a recording")
    with pytest.raises(ConfigError, match=r"notes\.mcap: not an MCAP recording"):
        replay_slam(notes, SlamParams())
