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
    sim, inputs = robot.extras["sim"], robot.extras["inputs"]
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
    health = robot.extras["health"].collect()
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
            inputs = robot.extras["inputs"]
            t = 0.0
            while t < 3.0:
                inputs.operate(Twist(0.25, 0.3), t)
                robot.run(until=t + 0.1)
                t = robot.clock.now()
            poses.append(robot.extras["sim"].pose)
    assert poses[0] == poses[1]
    assert not math.isclose(poses[0].x_m, 0.0)


def test_agent_starts_up_to_idle_and_reports_it_on_can(robot):
    agent, link = robot.parts["agent"], robot.parts["secondary_link"]
    robot.run(until=8.0)
    assert agent.state == "IDLE.MANUAL", agent.snapshot()["transitions"]
    assert link.status.state.name == "IDLE"
    assert robot.parts["secondary_core"].state == "ops"  # the board saw 0x150 byte 0 = 1
    assert robot.extras["localization"].localized


def test_a_goal_in_auto_is_reached_through_the_whole_stack(robot):
    """Dashboard-style commands → agent → navigator → motion pipeline → CAN → motors → simulated base."""
    agent, sim = robot.parts["agent"], robot.extras["sim"]
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
    assert robot.extras["localization"].map_pose().distance_to(goal) <= 0.25
    assert sim.pose.distance_to(goal) <= 0.25 + 0.10
    assert not sim.collisions
    assert robot.extras["navigation"].last_status.state == "SUCCEEDED"


def test_an_invalid_goal_goes_to_error_with_the_reason_and_back_to_idle(robot):
    agent = robot.parts["agent"]
    robot.run(until=6.0)
    agent.submit("set_auto")
    robot.run(until=6.5)
    agent.submit("goal", goal=Pose2D(100.0, 100.0, 0.0))
    robot.run(until=8.0)
    dests = [r.dest for r in agent.trace]
    assert "ERROR" in dests and agent.state.startswith("IDLE")
    error = next(r for r in agent.trace if r.dest == "ERROR")
    assert "outside the map" in error.reason


def test_every_run_records_a_trace_rotated_by_size(tmp_path):
    from atemr.fsm.trace_timeline import TraceTimeline
    from atemr.io.trace_file import read_trace

    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path), "can.channel": unique_channel("robot"), "ui.enabled": False,
        "secondary.portal_serve": False, "trace.max_file_mb": 0.004, "trace.max_files": 3})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        robot.run(duration=6.0)
    parts = sorted((tmp_path / "traces").glob("run-*.atrace"))
    assert len(parts) == 3  # rotated at 4 kB, the oldest parts deleted
    assert all(p.stat().st_size <= 0.004 * 1024 * 1024 for p in parts)
    newest = robot.extras["trace"].parts[-1]
    timeline = TraceTimeline(read_trace(newest).records)
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
        supervisor = robot.parts["can_bus"]
        assert supervisor.threaded is not simulation
        assert robot.parts["motors"].bus.supervisor is supervisor
        assert robot.parts["secondary_link"].bus.supervisor is supervisor
        assert robot.extras["health"].collect()["can_bus"].ok
    finally:
        robot.shutdown()


def test_the_supervisor_delivers_every_frame_of_the_running_robot(robot):
    robot.run(until=3.0)
    supervisor, link, driver = robot.parts["can_bus"], robot.parts["secondary_link"], robot.extras["driver"]
    assert supervisor.healthy and supervisor.frames > 0 and link.frames_in > 0
    assert all(state.last_reply_t is not None for state in driver.states.values())
