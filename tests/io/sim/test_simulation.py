"""The simulation as scheduler components: rates, determinism, default RMD wheels, subscribers."""

import dataclasses
import math

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.config import SimConfig
from atemr.errors import ConfigError
from atemr.io.motors.model import RmdMotorModel
from atemr.io.sim.simulation import SimParams, build_simulation, params_from_config
from atemr.scheduler import Scheduler


def drive(seed, *, camera_hz=0.0, seconds=3.0, world="studio"):
    sim = build_simulation(world, seed, params=SimParams(camera_hz=camera_hz))
    trajectory = []
    sim.physics.subscribe(lambda truth: trajectory.append((truth.t, truth.pose.x_m, truth.pose.y_m,
                                                           truth.pose.yaw_rad)))
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sim.command_twist(0.6, 0.4)
    sched.run(duration=seconds)
    return sim, np.array(trajectory)


def test_same_seed_same_world_same_trajectory():
    _, a = drive(7)
    _, b = drive(7)
    assert a.shape == (301, 4)
    assert np.array_equal(a, b)


def test_another_seed_another_trajectory():
    _, a = drive(7)
    _, b = drive(8)
    assert not np.array_equal(a, b)
    assert np.abs(a - b).max() < 0.2  # same commands: only noise differs


def test_the_camera_does_not_change_the_trajectory():
    sim_off, a = drive(7, seconds=1.0)
    sim_on, b = drive(7, camera_hz=10.0, seconds=1.0)
    assert np.array_equal(a, b)
    assert sim_off.camera_source.count == 0 and sim_on.camera_source.count == 11


def test_components_and_rates():
    sim = build_simulation("studio", 0, params=SimParams(camera_hz=5.0))
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sched.run(duration=2.0)
    counts = {c.name: c.ticks for c in sched.stats()}
    assert counts == {"sim.physics": 201, "sim.lidar": 21, "sim.imu": 101, "sim.cliff": 41, "sim.camera": 11}
    assert sim.lidar_source.latest is not None and sim.lidar_source.latest.t == 2.0
    assert sim.camera_source.latest.shape == (480, 640, 3)


def test_default_wheels_are_rmd_motor_models_with_first_order_dynamics():
    sim = build_simulation("studio", 0)
    assert isinstance(sim.left.model, RmdMotorModel) and isinstance(sim.right.model, RmdMotorModel)
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sim.command_wheels(10.0, 10.0)
    tau = sim.left.model.params.time_constant_s
    sched.run(duration=tau)
    assert sim.left.speed_radps == pytest.approx(10.0 * (1 - np.exp(-1)), rel=1e-6)
    # the right motor is mirrored: its shaft turns backwards while the robot drives forward
    assert sim.right.model.speed_radps == pytest.approx(-sim.left.speed_radps)
    assert sim.pose.x_m > sim.world.start.x_m


def test_motor_emulator_models_drive_the_base_over_can():
    import can

    from atemr.io.motors.emulator import RmdMotorEmulator
    from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest, motor_can_id
    from atemr.io.sim.base import MountedWheel

    channel = "test_sim_emulator_models"
    emulators = [RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), i, steps_model=False)
                 for i in (1, 2)]
    wheels = (MountedWheel(emulators[0].model, 1), MountedWheel(emulators[1].model, -1))
    sim = build_simulation("studio", 0, wheels=wheels)
    sched = Scheduler(SimClock())
    sim.attach(sched)
    for emulator in emulators:
        sched.add(emulator, 100.0)
    with can.Bus(interface="virtual", channel=channel) as driver:
        for _ in range(10):  # a driver repeats its command (the motors stop after 0.5 s without one)
            for motor_id, shaft in ((1, 5.0), (2, -5.0)):  # both wheels forward at 5 rad/s
                driver.send(RmdRequest(motor_id, RmdCommand.SPEED_CONTROL, speed_radps=shaft).encode())
            sched.run(duration=0.1)
        replies = [driver.recv(timeout=0) for _ in range(20)]
    sched.shutdown()
    for e in emulators:
        e.shutdown()
    assert all(r is not None for r in replies)
    assert {r.arbitration_id for r in replies} == {motor_can_id(1), motor_can_id(2)}
    # ~0.9 s at 5 rad/s x 0.085 m after the 80 ms rise, with slip
    assert 0.3 < sim.pose.x_m - sim.world.start.x_m < 0.43
    assert sim.pose.y_m == pytest.approx(sim.world.start.y_m, abs=0.03)


def test_a_failing_subscriber_does_not_stop_the_others(caplog):
    sim = build_simulation("studio", 0)
    got = []

    def broken(scan):
        raise RuntimeError("boom")

    sim.lidar_source.subscribe(broken)
    sim.lidar_source.subscribe(got.append)
    sim.lidar_source.tick(0.0)
    assert len(got) == 1
    assert "a subscriber failed" in caplog.text


def test_people_walk_and_pets_wander():
    sim = build_simulation("studio", 4)
    start = sim.movers.centres.copy()
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sched.run(duration=5.0)
    moved = np.hypot(*(sim.movers.centres - start).T)
    assert moved[0] > 1.0  # the carer walks 0.6 m/s along the path
    assert moved[1] > 0.0  # the cat has wandered


def test_a_pet_blocked_by_the_robot_wanders_elsewhere_and_a_person_waits():
    """A robot waiting for the cat and a cat waiting for the robot would stand in the doorway for ever."""
    from atemr.io.sim.movers import PET_PATIENCE_S

    sim = build_simulation("studio", 4)
    person, cat = sim.movers.items
    cat.x_m, cat.y_m, cat.goal, cat.pause_s = 6.2, 3.1, (8.2, 3.1), 0.0
    robot, radius = (6.7, 3.1), 0.3  # right in the cat's way, inside its personal space
    for _ in range(int(PET_PATIENCE_S / 0.05) - 2):
        sim.movers.step(0.05, robot, radius)
    assert cat.goal == (8.2, 3.1) and (cat.x_m, cat.y_m) == (6.2, 3.1)  # it waits a moment
    for _ in range(200):  # 10 s
        sim.movers.step(0.05, robot, radius)
    assert cat.goal != (8.2, 3.1) and math.dist((6.2, 3.1), (cat.x_m, cat.y_m)) > 0.3  # then goes elsewhere
    # a person whose path runs through the robot waits as long as it takes
    person.spec = dataclasses.replace(person.spec, path=((6.2, 3.1), (8.2, 3.1)))
    person.x_m, person.y_m, person.target, person.direction = 6.2, 3.1, 1, 1
    for _ in range(400):  # 20 s
        sim.movers.step(0.05, robot, radius)
    assert (person.x_m, person.y_m) == (6.2, 3.1)


def test_config_becomes_params():
    cfg = dataclasses.replace(SimConfig(), lidar_beams=400, camera_hz=0.0, wheel_slip=0.0)
    params = params_from_config(cfg)
    assert params.lidar.beams == 400 and params.camera_hz == 0.0 and params.base.slip_std == 0.0


def test_bad_seed_and_rates():
    with pytest.raises(ConfigError, match=r"sim\.seed"):
        build_simulation("studio", -1)
    with pytest.raises(ConfigError, match=r"sim\.lidar_hz"):
        SimParams(lidar_hz=0.0)


def test_interventions_from_another_thread_run_on_the_next_physics_tick():
    import threading

    from atemr.msgs import Pose2D

    sim = build_simulation("studio", 0)
    sched = Scheduler(SimClock())
    sim.attach(sched)
    futures = {}

    def dashboard():  # what the web server's thread does
        futures["kidnap"] = sim.submit(lambda: sim.kidnap(Pose2D(1.5, 4.0, 0.0)))
        futures["bad"] = sim.submit(lambda: sim.kidnap(Pose2D(-0.07, 2.0, 0.0)))
        futures["drop"] = sim.submit(lambda: sim.drop_obstacle(3.0, 1.0))

    worker = threading.Thread(target=dashboard)
    worker.start()
    worker.join()
    assert not futures["kidnap"].done()  # nothing changes between ticks
    sched.step()  # the first tick is the physics tick
    assert futures["kidnap"].result(timeout=0) is None
    assert sim.pose == Pose2D(1.5, 4.0, 0.0)
    with pytest.raises(ConfigError, match="overlaps wall"):
        futures["bad"].result(timeout=0)
    assert futures["drop"].result(timeout=0) in sim.scene.objects


def on_demand(seconds=1.0):
    """A simulation whose cameras render for consumers only (as the assembled robot's), run ``seconds``."""
    sim = build_simulation("studio", 0, params=SimParams(camera_hz=10.0, depth_hz=10.0, frames_on_demand=True))
    sched = Scheduler(SimClock())
    sim.attach(sched)
    return sim, sched


def test_frames_on_demand_render_nothing_for_nobody_and_the_camera_stays_healthy():
    from atemr.io.devices.sim import SimDevice

    sim, sched = on_demand()
    device = SimDevice("camera", sim.camera_source, max_age_s=1.0, what="camera frame", world="studio")
    sched.run(duration=1.0)
    assert sim.camera_source.count == 0 and sim.depth_source.count == 0
    assert sim.camera_source.skipped == 11
    assert device.health(1.0).ok  # it ticks: a camera nobody watches is not a silent one


def test_a_subscriber_takes_every_frame_and_a_registered_consumer_those_it_wants():
    sim, sched = on_demand()
    depth = []
    sim.depth_source.subscribe(depth.append)
    sim.camera_source.want("the second second", lambda now: 0.95 <= now < 1.95)
    sched.run(duration=3.0)
    assert len(depth) == 31
    assert sim.camera_source.count == 10  # the ticks at 1.0 .. 1.9 s
    sim.camera_source.want("the second second", lambda now: False)  # replaced
    sched.run(duration=1.0)
    assert sim.camera_source.count == 10


def test_a_request_renders_a_frame_now_only_when_the_newest_is_stale():
    sim, sched = on_demand()
    assert sim.camera_source.request(0.0) is None  # not running yet
    sched.run(duration=1.0)
    frame = sim.camera_source.request(sched.clock.now())
    assert frame is not None and frame.shape == (480, 640, 3) and sim.camera_source.count == 1
    assert sim.camera_source.request(sched.clock.now() + 0.05) is frame  # fresh enough: the same frame
    assert sim.camera_source.count == 1


def test_the_bare_simulator_renders_every_frame():
    sim, _ = drive(7, camera_hz=10.0, seconds=1.0)
    assert sim.camera_source.count == 11 and sim.camera_source.skipped == 0
