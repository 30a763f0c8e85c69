"""The map service: saving a map is all or nothing."""

import math

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.errors import AtemrError
from atemr.io.can.bus import unique_channel
from atemr.msgs import Twist
from atemr.robot import build_robot


@pytest.fixture
def robot(tmp_path):
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("map"),
                                                "secondary.portal_serve": False, "ui.enabled": False,
                                                "sim.camera_hz": 0})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        yield robot


CURVE = Twist(0.2, 0.3)


def drive(robot, until, twist=CURVE):
    inputs = robot.parts.inputs
    t = robot.clock.now()
    while t < until:
        inputs.operate(twist, t)
        robot.run(until=t + 0.1)
        t = robot.clock.now()


def test_a_refused_save_keeps_the_session_and_stores_nothing(robot):
    maps = robot.parts.maps
    robot.run(until=6.0)
    maps.begin()
    drive(robot, 12.0)
    with pytest.raises(AtemrError, match="built-in"):
        maps.end("studio", robot.clock.now())  # the built-in name is refused
    assert maps.slam is not None and maps.active_name == "studio"
    assert robot.parts.map_store.names() == ["studio"]
    stored = maps.end("living-room", robot.clock.now())
    assert stored == "living-room" and maps.active_name == "living-room" and maps.slam is None
    assert robot.parts.map_store.active_name() == "living-room"


def test_a_map_begun_while_localized_is_in_the_active_maps_frame(robot):
    """Mapping from a localized pose registers the first scan to the active map, so the saved map shares its
    frame: after the save the robot's pose on the new map is where it truly is in the world."""
    maps, sim = robot.parts.maps, robot.parts.sim
    robot.run(until=6.0)
    maps.begin()
    drive(robot, 14.0)
    assert maps.slam is not None and maps.slam.anchored
    texts = [e.text for e in robot.events if e.kind == "mapping"]
    assert "mapping started in the frame of map studio" in texts
    maps.end("living-room", robot.clock.now())
    robot.run(until=robot.clock.now() + 1.0)
    pose, truth = robot.parts.localization.map_pose(), sim.pose
    # the robot is localized on the saved map where the scan fits it; that map is SLAM's, itself up to about a
    # cell (5 cm) off the world in places
    assert pose is not None and pose.distance_to(truth) < 0.06, (pose, truth)
    assert abs(math.remainder(pose.yaw_rad - truth.yaw_rad, math.tau)) < 0.01, (pose, truth)
    # saving the map it made does not say "not localized": the carer read that beside "The robot knows where it is"
    said = [e.kind for e in robot.parts.localization.drain_events()]
    assert "initial_pose" in said and "map_changed" not in said, said


def test_a_saved_map_whose_end_pose_is_unusable_is_kept_and_says_not_localized(robot):
    """SLAM may end believing the robot stands where its own map is occupied (the edge of a wall). The map is
    stored and in use all the same (nothing half-saved), and the carer reads that the robot does not know where
    it is on it, instead of nothing at all."""
    maps = robot.parts.maps
    robot.run(until=6.0)
    maps.begin()
    drive(robot, 12.0)
    assert maps.slam is not None
    x, y = maps.slam.occupied_points()[0]
    maps.slam.pose = np.array([x, y, 0.0])
    robot.parts.localization.drain_events()
    assert maps.end("hall", robot.clock.now()) == "hall"
    assert maps.active_name == "hall" and robot.parts.map_store.active_name() == "hall" and maps.slam is None
    assert robot.parts.localization.map_pose() is None
    said = {e.kind: e.detail for e in robot.parts.localization.drain_events()}
    assert "map hall selected (the pose mapping ended at is not usable: " in said["map_changed"], said
    assert "initial_pose" not in said


def test_a_map_begun_unlocalized_starts_at_the_odometry_pose(robot):
    maps, localization = robot.parts.maps, robot.parts.localization
    robot.run(until=6.0)
    localization.start_global(robot.clock.now())  # the pose is unknown now
    assert localization.map_pose() is None
    # the agent's port says so: no pose on the map (a mission's final pose, its steps' errors and the recorded
    # poses would read an odometry pose as one on the map), while turning in place still has odometry to steer by
    port = robot.parts.port
    assert port.pose() is None and port.odom_pose() == localization.odom_pose
    maps.begin()
    drive(robot, 8.0)
    assert maps.slam is not None and not maps.slam.anchored
    assert "mapping started at the odometry pose" in [e.text for e in robot.events if e.kind == "mapping"]
