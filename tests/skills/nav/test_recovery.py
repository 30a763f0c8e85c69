import math

import pytest

from atemr.errors import NavigationError
from atemr.msgs import Pose2D
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.recovery import RecoveryBehaviour, RecoveryParams

RES = 0.05


@pytest.fixture
def open_room(make_map, make_room):
    return Costmap(make_map(make_room(80, 120), RES))  # 6 m x 4 m


def test_unknown_behaviour_is_refused():
    with pytest.raises(NavigationError, match="unknown behaviour"):
        RecoveryParams(sequence=("dance",))  # type: ignore[arg-type]


def test_rotate_recovery_turns_once_round(open_room):
    params = RecoveryParams()
    rec = RecoveryBehaviour("rotate in place", params, 0.0, Pose2D(2.0, 2.0, 0.0))
    yaw, t, done = 0.0, 0.0, False
    while not done:
        twist, done = rec.step(t, Pose2D(2.0, 2.0, math.atan2(math.sin(yaw), math.cos(yaw))), open_room)
        assert twist.linear_mps == 0.0
        yaw += twist.angular_radps * 0.1
        t += 0.1
    assert 2 * math.pi - 0.3 <= yaw <= 2 * math.pi + 0.1


def test_back_off_stops_at_its_distance_or_at_an_obstacle_behind(make_map, make_room, open_room):
    params = RecoveryParams()
    pose = Pose2D(3.0, 2.0, 0.0)
    rec = RecoveryBehaviour("back off", params, 0.0, pose)
    t, done = 0.0, False
    while not done:
        twist, done = rec.step(t, pose, open_room)
        pose = Pose2D(pose.x_m + twist.linear_mps * 0.1, pose.y_m, 0.0)
        t += 0.1
    assert 3.0 - pose.x_m == pytest.approx(params.backoff_distance_m, abs=0.02)
    # A wall right behind: it does not move at all.
    data = make_room(80, 120)
    data[:, 34] = 100  # wall at x = 1.7 m; the robot at 2.05 m is 0.35 m from it
    cm = Costmap(make_map(data, RES))
    rec = RecoveryBehaviour("back off", params, 0.0, Pose2D(2.05, 2.0, 0.0))
    twist, done = rec.step(0.0, Pose2D(2.05, 2.0, 0.0), cm)
    assert done and twist.is_zero


def test_clear_costmap_recovery_empties_the_obstacle_layer(open_room):
    open_room.obstacles[40, 60] = True
    open_room.version += 1
    rec = RecoveryBehaviour("clear costmap", RecoveryParams(), 0.0, Pose2D(1.0, 1.0, 0.0))
    twist, done = rec.step(0.0, Pose2D(1.0, 1.0, 0.0), open_room)
    assert done and twist.is_zero and not open_room.obstacles.any()
