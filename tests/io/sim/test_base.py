"""Differential-drive physics: exact kinematics, slip, collisions as events, run-time obstacles."""

import math

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.errors import ConfigError
from atemr.io.sim.base import BaseParams, DiffDriveBase, WheelMotor, integrate_arc
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.msgs import Pose2D
from atemr.scheduler import Scheduler

EXACT = SimParams(base=BaseParams(slip_std=0.0, odom_noise_std=0.0))


def run(sim, seconds):
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sched.run(duration=seconds)
    return sched


def test_wheel_double_and_motor_model_satisfy_the_protocol(ideal_wheels):
    from atemr.io.motors.model import RmdMotorModel

    assert isinstance(ideal_wheels[0], WheelMotor)
    assert isinstance(RmdMotorModel(), WheelMotor)


def test_integrate_arc_closes_a_circle():
    pose = Pose2D(1.0, 2.0, 0.3)
    for _ in range(100):
        pose = integrate_arc(pose, 0.5, 2 * math.pi / 10, 0.1)  # one full turn in 10 s
    assert (pose.x_m, pose.y_m, pose.yaw_rad) == pytest.approx((1.0, 2.0, 0.3), abs=1e-9)


def test_straight_line_without_slip_is_exact(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    sim.command_twist(0.5, 0.0)
    run(sim, 4.0)
    assert sim.pose.x_m == pytest.approx(3.0, abs=1e-9)
    assert sim.pose.y_m == pytest.approx(2.0, abs=1e-9)
    assert sim.odometry.x_m == pytest.approx(2.0, abs=1e-9)  # odometry starts at (0, 0, 0)
    assert sim.collisions == []


def test_turning_in_place(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [3.0, 2.0, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    sim.command_twist(0.0, math.pi / 2 / 1.6)
    run(sim, 1.6)
    assert sim.pose.yaw_rad == pytest.approx(math.pi / 2, abs=1e-6)
    assert (sim.pose.x_m, sim.pose.y_m) == (3.0, 2.0)


def test_slip_makes_truth_drift_from_odometry(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n"), 3,
                           params=SimParams(base=BaseParams(slip_std=0.05, odom_noise_std=0.0)), wheels=ideal_wheels)
    sim.command_twist(0.5, 0.0)
    run(sim, 4.0)
    travelled = sim.pose.x_m - 1.0
    assert 1.8 < travelled < 2.0  # slip only ever loses ground
    assert sim.odometry.x_m == pytest.approx(2.0, abs=1e-9)


def test_driving_into_a_wall_stops_there_and_reports_one_bump(make_world, ideal_wheels):
    # room 6 m x 4 m, 10 cm walls: the east wall's inner face is at x = 5.9
    sim = build_simulation(make_world("start: [4.0, 2.0, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    sim.command_twist(1.0, 0.0)
    run(sim, 4.0)
    assert len(sim.collisions) == 1
    bump = sim.collisions[0]
    assert bump.what == "wall"
    assert 5.9 - 0.25 - 0.02 <= bump.pose.x_m <= 5.9 - 0.25
    assert sim.pose.x_m <= 5.9 - 0.25 + 1e-9  # never through the wall
    assert sim.base.v_mps == 0.0
    # backing away is allowed, and driving in again is a second bump
    sim.command_twist(-0.5, 0.0)
    run(sim, 1.0)
    assert sim.pose.x_m < 5.3
    sim.command_twist(0.5, 0.0)
    run(sim, 3.0)
    assert len(sim.collisions) == 2


def test_turning_while_pressed_against_a_wall(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [5.6, 2.0, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    sim.command_twist(0.5, 1.0)
    run(sim, 0.5)
    assert sim.pose.yaw_rad == pytest.approx(0.5, abs=0.02)
    assert sim.pose.x_m <= 5.65 + 1e-9


def test_furniture_the_map_does_not_have_is_a_collision(make_world, ideal_wheels):
    world = make_world("start: [1.0, 2.0, 0.0]\nfurniture:\n  - {name: crate, box: [3.0, 1.5, 3.5, 2.5]}\n")
    sim = build_simulation(world, 0, params=EXACT, wheels=ideal_wheels)
    sim.command_twist(0.8, 0.0)
    run(sim, 4.0)
    assert [c.what for c in sim.collisions] == ["crate"]
    assert sim.pose.x_m == pytest.approx(3.0 - 0.25, abs=0.02)


def test_bumping_into_a_person(make_world, ideal_wheels):
    world = make_world("start: [1.0, 2.0, 0.0]\nmoving:\n"
                       "  - {name: visitor, kind: person, path: [[3.0, 2.0], [3.0, 2.01]], speed_mps: 0.001}\n")
    sim = build_simulation(world, 0, params=EXACT, wheels=ideal_wheels)
    sim.command_twist(0.8, 0.0)
    run(sim, 4.0)
    assert [c.what for c in sim.collisions] == ["visitor"]
    assert sim.pose.x_m == pytest.approx(3.0 - 0.22 - 0.25, abs=0.02)


def test_dropped_obstacle_blocks_and_can_be_removed(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    box = sim.drop_obstacle(3.0, 2.0, size_m=0.4)
    sim.command_twist(0.8, 0.0)
    run(sim, 3.0)
    assert [c.what for c in sim.collisions] == ["dropped box"]
    assert sim.pose.x_m == pytest.approx(2.8 - 0.25, abs=0.02)
    sim.remove_obstacle(box)
    run(sim, 1.0)
    assert sim.pose.x_m > 3.0
    with pytest.raises(ConfigError, match="no obstacle with id"):
        sim.remove_obstacle(box)
    with pytest.raises(ConfigError, match="outside the map"):
        sim.drop_obstacle(100.0, 100.0)


def test_kidnap(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    sim.kidnap(Pose2D(4.0, 3.0, 1.0))
    assert sim.pose == Pose2D(4.0, 3.0, 1.0)
    assert sim.odometry == Pose2D()  # the robot's own odometry does not notice
    with pytest.raises(ConfigError, match="overlaps wall"):
        sim.kidnap(Pose2D(5.8, 2.0, 0.0))
    with pytest.raises(ConfigError, match="outside the map"):
        sim.kidnap(Pose2D(-3.0, 2.0, 0.0))
    with pytest.raises(ConfigError, match="finite"):
        sim.kidnap(Pose2D(float("nan"), 2.0, 0.0))


def test_start_inside_an_obstacle_is_refused(make_world, ideal_wheels):
    with pytest.raises(ConfigError, match="overlaps wall"):
        build_simulation(make_world("start: [0.2, 2.0, 0.0]\n"), 0, wheels=ideal_wheels)


def test_base_parameters_are_validated():
    with pytest.raises(ConfigError, match=r"base\.track_m"):
        BaseParams(track_m=0.0)
    with pytest.raises(ConfigError, match=r"base\.slip_std"):
        BaseParams(slip_std=0.7)


def test_max_speed_is_enforced(ideal_wheels):
    left, right = ideal_wheels
    base = DiffDriveBase(left, right, params=BaseParams(slip_std=0.0, odom_noise_std=0.0),
                         rng=np.random.default_rng(0))
    left.set_speed(100.0)
    right.set_speed(100.0)
    for k in range(100):
        base.step(k * 0.01, 0.01)
    assert base.pose.x_m == pytest.approx(1.6, abs=1e-9)


def test_a_slow_physics_rate_does_not_tunnel_through_walls(make_world, ideal_wheels):
    # physics at 2 Hz (0.5 s between ticks) at full speed: 0.8 m per tick, the wall is 10 cm thick
    params = SimParams(base=BaseParams(slip_std=0.0, odom_noise_std=0.0), physics_hz=2.0)
    sim = build_simulation(make_world("start: [4.0, 2.0, 0.0]\n"), 0, params=params, wheels=ideal_wheels)
    sim.command_twist(1.6, 0.0)
    run(sim, 3.0)
    assert [c.what for c in sim.collisions] == ["wall"]
    assert 5.9 - 0.25 - 0.02 <= sim.pose.x_m <= 5.9 - 0.25
