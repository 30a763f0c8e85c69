"""The battery on the whole simulated robot (issue 27): the simulated pack supplies the motors, which report
its voltage in their status-1 replies (0x9A); the robot's estimate stays within 5 % of the simulator's true
charge while it drives, the dashboard shows it, and the limits act: a warning, then home to the dock, where
the pack charges."""

from __future__ import annotations

from typing import Any

from atemr.msgs import Pose2D
from atemr.robot import Robot

from .test_gateway import agent_state, make_robot, run


def boot(tmp_path: Any, **overrides: Any) -> tuple[Robot, Any]:
    robot, gateway = make_robot(tmp_path / "data", **overrides)
    robot.start()
    robot.run(until=4.0)
    assert agent_state(robot) == "IDLE.MANUAL"
    return robot, gateway


def drive_to(robot: Robot, gateway: Any, place: str, each: Any = None, limit_s: float = 150.0) -> None:
    """Send the robot to ``place`` from the Go to list and run until the agent is idle again."""
    assert gateway.go_to_place(place).ok, place
    run(robot, 0.3)
    end = robot.clock.now() + limit_s
    while robot.clock.now() < end:
        run(robot, 0.2)
        if each is not None:
            each()
        if agent_state(robot) == "IDLE.AUTO":
            return
    raise AssertionError(f"not at {place} within {limit_s:g} s")


def to_auto(robot: Robot, gateway: Any) -> None:
    for _ in range(40):
        gateway.set_mode("AUTO")
        run(robot, 0.5)
        if agent_state(robot) == "IDLE.AUTO":
            return
    raise AssertionError(agent_state(robot))


def test_the_estimate_follows_the_true_charge_while_driving(tmp_path):
    robot, gateway = boot(tmp_path, **{"sim.battery_wh": 2.0, "sim.battery_percent": 60.0, "sim.camera_hz": 0.0})
    try:
        pack, gauge = robot.parts.sim_battery, robot.parts.battery
        assert pack is not None
        to_auto(robot, gateway)
        errors: list[float] = []

        def compare() -> None:  # while it drives: on the dock the charger lifts the voltage (the start is there)
            status = gauge.status()
            if status is not None and robot.parts.sim.pose.distance_to(Pose2D(2.6, 2.6)) > 1.0:
                errors.append(abs(status.percent - pack.percent))

        for place in ("kitchen", "bedroom"):  # away from the dock (the start), where it would charge
            drive_to(robot, gateway, place, compare)
        assert len(errors) > 100 and pack.percent < 58.0, (len(errors), pack.percent)
        assert max(errors) <= 5.0, max(errors)
        state = gateway.state()["battery"]
        assert state is not None and abs(state["percent"] - pack.percent) <= 5.0 and state["level"] == "ok"
        assert gauge.estimator.rejected == 0
    finally:
        robot.stop()
        robot.shutdown()
        gateway.close()


def test_low_battery_warns_then_sends_the_robot_home_where_it_charges(tmp_path):
    robot, gateway = boot(tmp_path, **{"sim.battery_wh": 6.0, "sim.battery_percent": 11.5,
                                       "sim.battery_charge_s": 72.0, "sim.camera_hz": 0.0})
    try:
        pack, gauge = robot.parts.sim_battery, robot.parts.battery
        assert pack is not None
        to_auto(robot, gateway)
        assert gateway.go_to_place("kitchen").ok  # away from the dock; the pack runs down there
        texts: list[str] = []
        for _ in range(1500):
            run(robot, 0.2)
            texts = [e["text"] for e in gateway.state()["events"] if e["kind"] == "battery"]
            if pack.charging and pack.percent > 30.0:
                break
        assert any(t.startswith("battery low") for t in texts), texts
        assert any("goes home to charge" in t for t in texts), texts
        assert not any("critical" in t for t in texts), texts
        dock = robot.parts.maps.places["home"].pose
        assert robot.parts.sim.pose.distance_to(Pose2D(dock.x_m, dock.y_m)) < 0.3
        status = gauge.status()
        assert pack.charging and pack.percent > 30.0 and status is not None and status.level == "ok"
    finally:
        robot.stop()
        robot.shutdown()
        gateway.close()


def test_a_routine_is_skipped_on_a_low_battery(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "routines.yaml").write_text('routines:\n  - {name: check, mission: look-around, at: "09:00"}\n')
    robot, gateway = boot(tmp_path, **{"sim.battery_wh": 50.0, "sim.battery_percent": 8.0,
                                       "sim.battery_charge_s": 86_400.0, "sim.camera_hz": 0.0,
                                       "sim.start_time": "2026-06-03T08:59:00+00:00"})
    try:
        to_auto(robot, gateway)
        runner = robot.parts.routines
        run(robot, 60.0)
        runs = [(r["routine"], r["outcome"], r["reason"]) for r in runner.history]
        assert [r[:2] for r in runs] == [("check", "skipped")]
        reason = runs[0][2]  # the estimate of the 8 % pack, which stands on its dock (the charger lifts it a little)
        assert reason.startswith("battery ") and reason.endswith(" %") and int(reason.split()[1]) < 10, reason
    finally:
        robot.stop()
        robot.shutdown()
        gateway.close()
