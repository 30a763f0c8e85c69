import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.msgs import Pose2D, Twist
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.local_planner import LocalPlanner, LocalPlannerParams, rollout
from atemr.skills.nav.recovery import RecoveryBehaviour, RecoveryParams

RES = 0.05


@pytest.fixture
def open_room(make_map, make_room):
    return Costmap(make_map(make_room(80, 120), RES))  # 6 m x 4 m


def straight_path(x0, x1, y):
    xs = np.arange(x0, x1 + 1e-9, 0.05)
    return np.column_stack([xs, np.full_like(xs, y)])


def test_rollout_is_the_exact_arc():
    times = np.array([0.5, 1.0])
    x, y, th = rollout(Pose2D(1.0, 2.0, 0.0), np.array([0.5, 0.5]), np.array([0.0, math.pi / 2]), times)
    assert x[0].tolist() == pytest.approx([1.25, 1.5])
    assert y[0].tolist() == pytest.approx([2.0, 2.0])
    radius = 0.5 / (math.pi / 2)
    assert x[1, 1] == pytest.approx(1.0 + radius) and y[1, 1] == pytest.approx(2.0 + radius)
    assert th[1, 1] == pytest.approx(math.pi / 2)


def test_follows_a_straight_path_within_the_limits(open_room):
    params = LocalPlannerParams()
    lp = LocalPlanner(open_room, params)
    path = straight_path(1.0, 5.0, 2.0)
    v0 = Twist(0.3, 0.0)
    plan = lp.compute(Pose2D(1.0, 2.0, 0.0), v0, path, (5.0, 2.0), 0.1)
    assert plan.ok and plan.valid > 0
    assert plan.twist.linear_mps == pytest.approx(0.3 + params.linear_accel_mps2 * 0.1)
    assert abs(plan.twist.angular_radps) < 0.1
    # From rest it can only speed up by a * dt.
    plan = lp.compute(Pose2D(1.0, 2.0, 0.0), Twist(), path, (5.0, 2.0), 0.1)
    assert 0 < plan.twist.linear_mps <= params.linear_accel_mps2 * 0.1 + 1e-12
    # At top speed it stays at or below the limit.
    plan = lp.compute(Pose2D(1.0, 2.0, 0.0), Twist(params.max_linear_mps, 0.0), path, (5.0, 2.0), 0.1)
    assert plan.twist.linear_mps <= params.max_linear_mps + 1e-12


def test_steers_back_onto_the_path(open_room):
    lp = LocalPlanner(open_room)
    path = straight_path(1.0, 5.0, 2.0)
    plan = lp.compute(Pose2D(1.5, 1.7, 0.0), Twist(0.3, 0.0), path, (5.0, 2.0), 0.1)
    assert plan.twist.angular_radps > 0.05  # the path is to the left


def test_turns_on_the_spot_when_the_path_is_behind(open_room):
    lp = LocalPlanner(open_room)
    path = straight_path(1.0, 5.0, 2.0)[::-1]  # towards -x
    plan = lp.compute(Pose2D(4.0, 2.0, 0.0), Twist(), path, (1.0, 2.0), 0.1)
    assert plan.twist.linear_mps == 0.0 and plan.twist.angular_radps != 0.0


def test_slows_for_the_goal_and_stops_there(open_room):
    from atemr.io.sim.base import integrate_arc

    params = LocalPlannerParams()
    lp = LocalPlanner(open_room, params)
    path = straight_path(1.0, 3.0, 2.0)
    pose, v = Pose2D(1.0, 2.0, 0.0), Twist(params.max_linear_mps, 0.0)
    for _ in range(60):
        plan = lp.compute(pose, v, path, (3.0, 2.0), 0.1)
        assert abs(plan.twist.linear_mps - v.linear_mps) <= params.linear_accel_mps2 * 0.1 + 1e-9
        v = plan.twist
        pose = integrate_arc(pose, v.linear_mps, v.angular_radps, 0.1)
    assert abs(pose.x_m - 3.0) < 0.1 and abs(pose.y_m - 2.0) < 0.05
    assert v.linear_mps < 0.1


def test_never_drives_into_a_wall_ahead(make_map, make_room):
    data = make_room(80, 120)
    data[:, 50] = 100  # a wall across the room at x = 2.5 m
    cm = Costmap(make_map(data, RES))
    lp = LocalPlanner(cm)
    path = straight_path(1.5, 5.0, 2.0)  # a (stale) path straight through the wall
    pose = Pose2D(2.1, 2.0, 0.0)
    plan = lp.compute(pose, Twist(0.4, 0.0), path, (5.0, 2.0), 0.1)
    if plan.ok:
        clear = cm.distance_at(plan.trajectory[:, 0], plan.trajectory[:, 1])
        assert (clear >= cm.params.inscribed_radius_m - 1e-6).all()
    # Pressed against it (inside the inscribed zone), only moves that get farther away are allowed.
    pose = Pose2D(2.3, 2.0, 0.0)
    plan = lp.compute(pose, Twist(), path, (5.0, 2.0), 0.1)
    ends = plan.trajectory[-1]
    assert cm.distance_at(ends[0], ends[1]) >= cm.distance_at(pose.x_m, pose.y_m)


def test_bad_params_are_navigation_errors():
    with pytest.raises(NavigationError, match="max_linear_mps"):
        LocalPlannerParams(max_linear_mps=0.0)
    with pytest.raises(NavigationError, match="samples"):
        LocalPlannerParams(angular_samples=1)
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
