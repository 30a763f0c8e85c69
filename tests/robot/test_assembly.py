"""The assembled robot in simulation: CAN motors, secondary core, motion control, end to end."""

import math

import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.io.can.bus import unique_channel
from atemr.msgs import Pose2D, Twist
from atemr.robot import build_robot


@pytest.fixture
def robot(tmp_path):
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("robot"),
                                                "sim.seed": 1, "secondary.portal_serve": False, "ui.enabled": False})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        yield robot


def test_joystick_drives_the_simulated_base_over_can_and_a_lost_joystick_stops_it(robot):
    sim, inputs = robot.parts.sim, robot.parts.inputs
    robot.run(until=3.0)  # boot: secondary core ready, heartbeat established
    start = sim.pose
    t = robot.clock.now()
    while t < 5.0:  # the operator holds "forward" for 2 s, resending as the page does
        inputs.operate(Twist(0.3, 0.0), t)
        robot.run(until=t + 0.1)
        t = robot.clock.now()
    moved = sim.pose.x_m - start.x_m
    assert moved > 0.3, f"the base should have driven forward, moved {moved:.2f} m"
    assert abs(sim.pose.y_m - start.y_m) < 0.1
    robot.run(until=5.6)  # joystick silent: the mux drops it after 0.5 s, the ramp is bypassed
    before = sim.pose
    robot.run(until=6.5)
    assert before.distance_to(sim.pose) < 0.02
    assert not sim.collisions


def test_health_reports_every_hardware_component(robot):
    robot.run(until=4.0)  # the secondary core boots for 3 s, then publishes the IR sensors
    health = robot.parts.health.collect()
    for name in ("left_motor", "right_motor", "lidar", "imu", "ir_front", "ir_rear", "connectivity"):
        assert health[name].ok, (name, health[name])


def test_runs_are_deterministic(tmp_path):
    poses = []
    for _ in range(2):
        config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("det"),
                                                    "sim.seed": 7, "secondary.portal_serve": False,
                                                    "ui.enabled": False})
        robot = build_robot(config, realtime=False, clock=SimClock())
        with robot:
            inputs = robot.parts.inputs
            t = 0.0
            while t < 3.0:
                inputs.operate(Twist(0.25, 0.3), t)
                robot.run(until=t + 0.1)
                t = robot.clock.now()
            poses.append(robot.parts.sim.pose)
    assert poses[0] == poses[1]
    assert not math.isclose(poses[0].x_m, 0.0)


def test_agent_starts_up_to_idle_and_reports_it_on_can(robot):
    agent, link = robot.components["agent"], robot.components["secondary_link"]
    robot.run(until=8.0)
    assert agent.state == "IDLE.MANUAL", agent.snapshot()["transitions"]
    assert link.status.state.name == "IDLE"
    assert robot.components["secondary_core"].state == "ops"  # the board saw 0x150 byte 0 = 1
    assert robot.parts.localization.localized


def test_a_goal_in_auto_is_reached_through_the_whole_stack(robot):
    """Dashboard-style commands → agent → navigator → motion pipeline → CAN → motors → simulated base."""
    agent, sim = robot.components["agent"], robot.parts.sim
    robot.run(until=6.0)
    agent.submit("set_auto")
    robot.run(until=6.5)
    goal = Pose2D(6.0, 1.1, 0.0)
    agent.submit("goal", goal=goal)
    robot.run(until=7.0)
    assert agent.state == "EXEC"
    t = 7.0
    while agent.state == "EXEC" and t < 60.0:
        t += 1.0
        robot.run(until=t)
    assert agent.state == "IDLE.AUTO", agent.trace[-3:]
    # The navigator stops within 0.25 m of the goal by its *estimated* pose; the true pose may differ
    # by the localization error (target RMSE < 0.10 m).
    assert robot.parts.localization.map_pose().distance_to(goal) <= 0.25
    assert sim.pose.distance_to(goal) <= 0.25 + 0.10
    assert not sim.collisions
    assert robot.parts.navigation.last_status.state == "SUCCEEDED"


def test_an_invalid_goal_goes_to_error_with_the_reason_and_back_to_idle(robot):
    agent = robot.components["agent"]
    robot.run(until=6.0)
    agent.submit("set_auto")
    robot.run(until=6.5)
    agent.submit("goal", goal=Pose2D(100.0, 100.0, 0.0))
    robot.run(until=8.0)
    dests = [r.dest for r in agent.trace]
    assert "ERROR" in dests and agent.state.startswith("IDLE")
    error = next(r for r in agent.trace if r.dest == "ERROR")
    assert "outside the map" in error.reason


def test_every_run_records_to_mcap_rotated_by_size(tmp_path):
    from atemr.fsm.trace_timeline import TraceTimeline
    from atemr.io.recording.agent_trace import read_agent_trace

    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path), "can.channel": unique_channel("robot"), "ui.enabled": False,
        "secondary.portal_serve": False, "trace.max_file_mb": 0.06, "trace.max_files": 3,
        "trace.depth_hz": 0.0})  # one depth frame (200 kB before compression) is bigger than these 60 kB parts
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        robot.run(duration=6.0)
    parts = sorted((tmp_path / "traces").glob("run-*.mcap"))
    assert len(robot.parts.trace.parts) > 3 and len(parts) == 3  # rotated at 60 kB, the oldest parts deleted
    assert all(p.stat().st_size <= 0.06 * 1024 * 1024 for p in parts)
    newest = robot.parts.trace.parts[-1]
    timeline = TraceTimeline(read_agent_trace(newest).records)
    assert timeline.head["meta"] == {"world": "studio", "seed": 0, "map": "studio", "simulation": True}
    end = timeline.frame(1e9)
    assert end["state"] == "IDLE.MANUAL" and end["tree"]["name"] == "manual" and end["pose"] is not None
    assert end["blackboard"]["/agent/state"]["by"] == "agent/agent"


@pytest.mark.parametrize("simulation", [True, False])
def test_the_primary_receives_through_one_supervisor_polled_in_simulation_threaded_on_the_robot(tmp_path, simulation):
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("sup"),
                                                "simulation": simulation, "secondary.portal_serve": False,
                                                "ui.enabled": False})
    robot = build_robot(config, realtime=False, clock=SimClock())  # built, not started: no thread runs
    try:
        supervisor = robot.components["can_bus"]
        assert supervisor.threaded is not simulation
        assert robot.components["motors"].bus.supervisor is supervisor
        assert robot.components["secondary_link"].bus.supervisor is supervisor
        assert robot.parts.health.collect()["can_bus"].ok
    finally:
        robot.shutdown()


def test_the_supervisor_delivers_every_frame_of_the_running_robot(robot):
    robot.run(until=3.0)
    supervisor, link, driver = robot.components["can_bus"], robot.components["secondary_link"], robot.parts.driver
    assert supervisor.healthy and supervisor.frames > 0 and link.frames_in > 0
    assert all(state.last_reply_t is not None for state in driver.states.values())


def test_motors_with_protocol_v4_drive_the_base_and_answer_on_0x240(tmp_path):
    """``devices.motors.protocol: v4``: the driver and both emulators speak RMD V4.2 (replies on 0x240 + id), and
    the robot drives as with V1.61."""
    import can

    channel = unique_channel("v4")
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": channel, "sim.seed": 1,
                                                "secondary.portal_serve": False, "ui.enabled": False,
                                                "devices.motors.protocol": "v4"})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with can.Bus(interface="virtual", channel=channel) as tap, robot:
        sim, inputs = robot.parts.sim, robot.parts.inputs
        robot.run(until=3.0)
        start = sim.pose
        t = robot.clock.now()
        while t < 5.0:
            inputs.operate(Twist(0.3, 0.0), t)
            robot.run(until=t + 0.1)
            t = robot.clock.now()
        frames = []
        while (msg := tap.recv(timeout=0)) is not None:
            frames.append(msg)
        assert sim.pose.x_m - start.x_m > 0.3
        assert robot.parts.health.collect()["left_motor"].ok and robot.parts.driver.fault is None
        assert {0x241, 0x242} <= {m.arbitration_id for m in frames}  # the V4.2 replies
        requests = [m for m in frames if m.arbitration_id in (0x141, 0x142)]
        assert requests and not [m for m in requests if m.data[0] in (0x88, 0x9B)]  # V4.2 has neither


@pytest.mark.parametrize(("simulation", "key"), [(True, "sim.lidar_range_m"), (False, "devices.lidar.range_max_m")])
def test_localization_covers_the_range_the_lidar_is_set_to(tmp_path, simulation, key):
    """A lidar set to use its returns to 12 m (an A2M8 after revision R3) has localization's likelihood model
    and global search cover 12 m too, simulated or real."""
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("range"),
                                                "simulation": simulation, "secondary.portal_serve": False,
                                                "ui.enabled": False, key: 12.0})
    robot = build_robot(config, realtime=False, clock=SimClock())  # built, not started
    try:
        params = robot.parts.localization.localizer_params
        assert params.global_search.range_max_m == 12.0 and params.amcl.field.range_max_m == 12.0
        if simulation:
            assert robot.parts.sim.lidar.params.range_max_m == 12.0
    finally:
        robot.shutdown()


def test_a_headless_robot_renders_no_camera_frame_until_a_picture_is_taken(tmp_path):
    from atemr.robot.headless import build_headless_robot

    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "sim.seed": 1})
    robot = build_headless_robot(config)  # no dashboard, no recording: nobody watches the camera
    with robot:
        sim = robot.parts.sim
        robot.run(until=2.0)
        assert sim.params.camera_hz > 0 and sim.camera_source.count == 0 and sim.camera_source.skipped == 21
        assert robot.parts.health.collect()["camera"].ok
        stored = robot.parts.port.capture_image("kitchen")
        assert stored.endswith(".jpg") and sim.camera_source.count == 1
        assert sim.depth_source.count == 21 and not sim.depth_source.skipped  # the depth layer takes every frame


def test_a_recording_alone_renders_the_depth_frames_it_keeps(tmp_path):
    """With the depth layer off, only the recording wants depth frames: the simulated D415 renders one a second
    (trace.depth_hz) rather than ten, each when the recording takes it, so every rendered frame is recorded;
    trace.depth_hz 0 records none and renders none."""
    from mcap.reader import make_reader

    from atemr.robot.headless import build_headless_robot

    for depth_hz, recorded in ((1.0, range(3, 5)), (0.0, range(0, 1))):
        folder = tmp_path / f"hz{depth_hz}"
        config = load_config(environ={}, overrides={
            "data_dir": str(folder), "sim.seed": 1, "nav.depth_layer": False, "trace.depth_hz": depth_hz,
            "trace.file": str(folder / "run.mcap")})
        robot = build_headless_robot(config)
        with robot:
            robot.run(until=3.0)
            rendered = robot.parts.sim.depth_source.count
        with open(folder / "run.mcap", "rb") as handle:
            kept = sum(1 for _ in make_reader(handle).iter_messages(topics=["/camera/depth/image_rect_raw"]))
        assert kept in recorded, (depth_hz, kept)
        # rendered when the recording's next frame is due, and only then: one rendered per kept one, not 31
        assert rendered == kept, (depth_hz, rendered, kept)
