"""Lidar, IMU and cliff sensors against worlds with known geometry."""

import math

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.errors import ConfigError
from atemr.io.sim.base import BaseParams
from atemr.io.sim.cliff import CliffParams
from atemr.io.sim.imu import ImuParams
from atemr.io.sim.lidar import Lidar, LidarParams
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.io.sim.world import Furniture
from atemr.msgs import Pose2D
from atemr.scheduler import Scheduler

QUIET_BASE = BaseParams(slip_std=0.0, odom_noise_std=0.0)
EXACT = SimParams(base=QUIET_BASE, lidar=LidarParams(noise_std_m=0.0, dropout_prob=0.0),
                  cliff=CliffParams(noise_std_m=0.0))


def run(sim, seconds):
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sched.run(duration=seconds)
    return sched


def beam(scan, angle):
    return scan.ranges_m[round((angle - scan.angle_min_rad) / scan.angle_increment_rad)]


def test_lidar_sees_the_walls_at_known_distances(make_world, ideal_wheels):
    # inner faces: x = 0.1 and 5.9, y = 0.1 and 3.9; the lidar is 10 cm ahead of the base centre
    sim = build_simulation(make_world("start: [2.0, 1.5, 0.0]\n"), 0, params=EXACT, wheels=ideal_wheels)
    scan = sim.read_lidar(0.0)
    assert len(scan.ranges_m) == 360
    assert scan.angle_increment_rad == pytest.approx(math.radians(1.0))
    assert scan.sensor_pose.x_m == 0.10
    assert beam(scan, 0.0) == pytest.approx(5.9 - 2.1)
    assert beam(scan, math.pi / 2) == pytest.approx(3.9 - 1.5)
    assert beam(scan, -math.pi / 2) == pytest.approx(1.5 - 0.1)
    assert beam(scan, -math.pi) == pytest.approx(2.1 - 0.1)


def test_lidar_rotates_with_the_robot(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [3.0, 2.0, 1.5707963267948966]\n"), 0, params=EXACT,
                           wheels=ideal_wheels)
    scan = sim.read_lidar(0.0)
    # facing +y: the beam straight ahead meets y = 3.9 from y = 2.1 (mount offset now along y)
    assert beam(scan, 0.0) == pytest.approx(1.8)
    assert beam(scan, math.pi / 2) == pytest.approx(3.0 - 0.1)  # to the robot's left is -x


def test_lidar_range_limits(make_world, ideal_wheels):
    params = SimParams(base=QUIET_BASE, lidar=LidarParams(range_min_m=2.0, range_max_m=3.0, noise_std_m=0.0,
                                                           dropout_prob=0.0))
    sim = build_simulation(make_world("start: [2.0, 1.5, 0.0]\n", width_m=12.0), 0, params=params,
                           wheels=ideal_wheels)
    scan = sim.read_lidar(0.0)
    assert beam(scan, 0.0) == math.inf  # wall 9.8 m away, beyond 3 m
    assert beam(scan, -math.pi / 2) == -math.inf  # 1.4 m, closer than the minimum
    assert beam(scan, math.pi / 2) == pytest.approx(2.4)
    # a device that measures no farther than 9 m returns nothing from that wall: no return, NaN
    short = SimParams(base=QUIET_BASE, lidar=LidarParams(range_min_m=2.0, range_max_m=3.0, noise_std_m=0.0,
                                                          dropout_prob=0.0, reach_m=9.0))
    sim = build_simulation(make_world("start: [2.0, 1.5, 0.0]\n", width_m=12.0), 0, params=short,
                           wheels=ideal_wheels)
    scan = sim.read_lidar(0.0)
    assert math.isnan(beam(scan, 0.0)) and beam(scan, -math.pi / 2) == -math.inf
    assert beam(scan, math.pi / 2) == pytest.approx(2.4)
    with pytest.raises(ConfigError, match="reach_m"):
        LidarParams(range_max_m=8.0, reach_m=6.0)


def test_lidar_noise_and_dropouts(make_world, ideal_wheels):
    params = SimParams(base=QUIET_BASE, lidar=LidarParams(beams=3600, noise_std_m=0.02, dropout_prob=0.1))
    sim = build_simulation(make_world("start: [3.0, 2.0, 0.0]\n"), 5, params=params, wheels=ideal_wheels)
    truth = sim.lidar.true_ranges(sim.pose, sim.scene, sim.movers.centres, sim.movers.radii)
    scan = sim.read_lidar(0.0)
    dropped = np.isnan(scan.ranges_m)  # no return, as the device reports a dark spot (not +inf: beyond range)
    assert 0.07 < dropped.mean() < 0.13 and not np.isinf(scan.ranges_m).any()
    err = scan.ranges_m[~dropped] - truth[~dropped]
    assert abs(err.mean()) < 0.003
    assert err.std() == pytest.approx(0.02, rel=0.1)


def test_furniture_people_and_dropped_obstacles_appear_in_the_scan(make_world, ideal_wheels):
    world = make_world(
        "start: [1.0, 2.0, 0.0]\n"
        "furniture:\n  - {name: crate, box: [3.0, 1.5, 3.5, 2.5]}\n"
        "moving:\n  - {name: visitor, kind: person, path: [[1.0, 3.3], [1.0, 3.31]], speed_mps: 0.001}\n"
    )
    sim = build_simulation(world, 0, params=EXACT, wheels=ideal_wheels)
    scan = sim.read_lidar(0.0)
    assert beam(scan, 0.0) == pytest.approx(3.0 - 1.1)  # the crate, not the wall at 5.9
    # the person (r = 0.22) at (1.0, 3.3) seen from the lidar at (1.1, 2.0)
    d = beam(scan, math.atan2(1.3, -0.1))
    assert d == pytest.approx(math.hypot(0.1, 1.3) - 0.22, abs=0.01)
    sim.drop_obstacle(1.1, 1.0, size_m=0.2)
    assert beam(sim.read_lidar(0.0), -math.pi / 2) == pytest.approx(2.0 - 1.1)


def test_cliff_sensors_read_the_floor_then_out_of_range_over_a_drop(make_world, ideal_wheels):
    world = make_world("start: [3.0, 2.0, 0.0]\n"
                       "drop_zones:\n  - {name: stairs, box: [4.5, 0.1, 5.9, 3.9], depth_m: 1.0}\n")
    sim = build_simulation(world, 0, params=EXACT, wheels=ideal_wheels)
    first = sim.read_cliff(0.0)
    assert (first.front_left_m, first.front_right_m, first.rear_m) == (0.06, 0.06, 0.06)
    readings = []
    sim.cliff_source.subscribe(readings.append)
    sim.command_twist(0.4, 0.0)
    run(sim, 4.0)
    over = [r for r in readings if math.isinf(r.front_left_m)]
    assert over, "the front sensors never saw the drop"
    assert all(math.isinf(r.front_right_m) and r.rear_m == 0.06 for r in over[:5])
    # the front sensors are 20 cm ahead of the centre: they see the edge when the centre is ~0.2 m short of it
    t_edge = over[0].t
    assert 3.0 + 0.4 * t_edge == pytest.approx(4.5 - 0.20, abs=0.4 * 0.05 + 1e-9)
    # kept driving: the robot went over the edge and is stuck there
    assert sim.falls and sim.falls[0].zone == "stairs"
    assert 4.5 <= sim.pose.x_m < 4.6


def test_a_shallow_step_reads_within_range(make_world, ideal_wheels):
    world = make_world("start: [4.9, 2.0, 0.0]\n"
                       "drop_zones:\n  - {name: step, box: [5.05, 0.1, 5.9, 3.9], depth_m: 0.1}\n")
    sim = build_simulation(world, 0, params=EXACT, wheels=ideal_wheels)
    r = sim.read_cliff(0.0)
    assert r.front_left_m == pytest.approx(0.16) and r.rear_m == pytest.approx(0.06)


def test_cliff_params_are_validated():
    with pytest.raises(ConfigError, match="within the sensor range"):
        CliffParams(floor_distance_m=0.5)


def test_imu_bias_noise_and_turn_rate(make_world, ideal_wheels):
    params = SimParams(base=QUIET_BASE, imu=ImuParams(gyro_noise_std_radps=0.01, gyro_bias_std_radps=0.005))
    sim = build_simulation(make_world("start: [3.0, 2.0, 0.0]\n"), 11, params=params, wheels=ideal_wheels)
    samples = []
    sim.imu_source.subscribe(samples.append)
    sim.command_twist(0.0, 0.5)
    run(sim, 4.0)
    rates = np.array([s.yaw_rate_radps for s in samples[5:]])
    assert rates.mean() == pytest.approx(0.5 + sim.imu.gyro_bias_radps, abs=0.004)
    assert rates.std() == pytest.approx(0.01, rel=0.2)
    assert sim.imu.gyro_bias_radps != 0.0
    assert len(samples) == 201


def test_imu_sees_acceleration_and_a_bump(make_world):
    from atemr.io.motors.model import RmdMotorModel

    sim = build_simulation(make_world("start: [4.0, 2.0, 0.0]\n"), 0, params=SimParams(base=QUIET_BASE),
                           wheels=(RmdMotorModel(), RmdMotorModel()))
    samples = []
    sim.imu_source.subscribe(samples.append)
    sim.command_twist(1.0, 0.0)
    run(sim, 3.0)
    ax = np.array([s.accel_x_mps2 for s in samples])
    assert ax[1:5].max() > 3.0  # speeding up with the motors' 80 ms time constant
    assert ax.min() < -20.0  # the bump: a sudden stop, clipped at the accelerometer's range
    assert ax.min() >= -4 * 9.80665


def test_a_standing_lidar_casts_what_does_not_move_once_and_sees_what_does() -> None:
    """A robot standing still scans the same walls and furniture revolution after revolution, so the lidar keeps
    that cast for its pose and casts only the people and pets again: its ranges are, to the bit, a fresh lidar's
    while the carer and the cat walk, a crate put down or taken away is in the next scan, and what it hands out
    may be written to without spoiling what it keeps."""
    sim = build_simulation("studio", 4)
    pose = Pose2D(3.0, 2.6, 1.45)
    standing = Lidar(LidarParams(), np.random.default_rng(0))

    def fresh() -> np.ndarray:
        return Lidar(LidarParams(), np.random.default_rng(0)).true_ranges(pose, sim.scene, sim.movers.centres,
                                                                           sim.movers.radii)

    first = standing.true_ranges(pose, sim.scene, sim.movers.centres, sim.movers.radii)
    kept = standing._static
    first[:] = -1.0  # the caller's to change
    changed = 0
    for k in range(1, 60):
        sim.step_to(k * 0.5)
        ranges = standing.true_ranges(pose, sim.scene, sim.movers.centres, sim.movers.radii)
        assert ranges.tobytes() == fresh().tobytes(), k
        assert standing._static is kept  # the cast was kept, not made again
        changed += ranges.tobytes() != kept[1].tobytes()
    assert changed > 20, changed  # the carer walked through the scan meanwhile
    alone = standing.true_ranges(pose, sim.scene, np.zeros((0, 2)), np.zeros(0))
    assert alone.tobytes() == kept[1].tobytes() and alone.flags.writeable
    crate = sim.scene.add_object(Furniture("crate", "box", (2.9, 3.4, 3.3, 3.7), 0.6))
    assert standing.true_ranges(pose, sim.scene, sim.movers.centres, sim.movers.radii).tobytes() == fresh().tobytes()
    sim.scene.remove_object(crate)
    assert standing.true_ranges(pose, sim.scene, sim.movers.centres, sim.movers.radii).tobytes() == fresh().tobytes()
