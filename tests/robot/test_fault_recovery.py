"""Clearing recoverable hardware faults: the health board's recoveries, the port's `clear_faults`, and the
assembled robot's Error state holding until a latched motor fault can be cleared, then driving again."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.domain.status import ComponentHealth
from atemr.io.can.bus import unique_channel
from atemr.io.motors.rmd_codec import MotorErrorFlags
from atemr.msgs import Twist
from atemr.robot import build_robot
from atemr.robot.core import Robot
from atemr.robot.health import HealthBoard
from atemr.trees.ports import RobotPort


def test_health_board_runs_every_recovery_and_joins_the_reasons() -> None:
    board = HealthBoard(now=lambda: 0.0)
    assert board.clear_faults() is None  # nothing registered, nothing latched
    calls: list[str] = []

    def cleared() -> str | None:
        calls.append("a")
        return None

    def latched() -> str | None:
        calls.append("b")
        return "left motor (id 1) not answering"

    def broken() -> str | None:
        raise RuntimeError("boom")

    board.add_recovery("a", cleared)
    assert board.clear_faults() is None
    board.add_recovery("b", latched)
    board.add_recovery("c", broken)
    assert board.clear_faults() == "b: left motor (id 1) not answering; c: clearing failed: boom"
    assert calls == ["a", "a", "b"]


@pytest.fixture
def robot(tmp_path: Any) -> Iterator[Robot]:
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("recovery"),
                                                "sim.seed": 5, "secondary.portal_serve": False, "ui.enabled": False})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        robot.run(until=7.0)
        assert robot.components["agent"].state == "IDLE.MANUAL"  # type: ignore[attr-defined]
        yield robot


FORWARD = Twist(0.2, 0.0)


def drive(robot: Robot, until: float, twist: Twist = FORWARD) -> None:
    inputs = robot.parts.inputs
    t = robot.clock.now()
    while t < until - 1e-9:
        inputs.operate(twist, t)
        robot.run(until=min(until, t + 0.1))
        t = robot.clock.now()


def test_the_port_clears_the_driver_fault_only_once_both_motors_answer(robot: Robot) -> None:
    port = robot.parts.port
    assert isinstance(port, RobotPort)
    driver = robot.parts.driver
    left = robot.components["left_motor_emulator"]
    assert port.clear_faults() is None  # nothing latched
    left.model.unplug()  # type: ignore[attr-defined]
    robot.run(until=robot.clock.now() + 0.5)
    assert driver.fault is not None
    why = port.clear_faults()
    assert why is not None and "left motor (id 1) not answering" in why
    assert driver.fault is not None, "a silent motor keeps the fault latched"
    left.model.plug()  # type: ignore[attr-defined]
    robot.run(until=robot.clock.now() + 0.1)  # the driver's polls are answered again
    assert port.clear_faults() is None
    assert driver.fault is None
    robot.run(until=robot.clock.now() + 0.1)
    assert port.health()["left_motor"] == ComponentHealth(True)


def test_an_over_temperature_that_cools_down_is_cleared_and_the_robot_drives_again(robot: Robot) -> None:
    agent: Any = robot.components["agent"]
    left: Any = robot.components["left_motor_emulator"]
    right: Any = robot.components["right_motor_emulator"]
    driver = robot.parts.driver
    fault_t = robot.clock.now()
    right.model.inject_error(MotorErrorFlags.OVER_TEMPERATURE)
    drive(robot, fault_t + 2.0)
    # the flag is latched in the motor while its cause lasts: the agent holds ERROR and the motors stay at zero
    assert agent.state == "ERROR" and driver.fault is not None
    assert [m.model.target_radps for m in (left, right)] == [0.0, 0.0]
    assert "OVER_TEMPERATURE" in agent.snapshot()["tree"]["children"][-1]["feedback"]
    # the winding cools down: the cause is gone but the flag stays latched until CLEAR_ERRORS (0x9B), which the
    # Error state's recovery sends; then the driver's fault is reset and the agent goes back to IDLE
    right.model.clear_injected()
    assert right.model.error_flags == MotorErrorFlags.OVER_TEMPERATURE
    back_t = robot.clock.now()
    drive(robot, back_t + 1.0)
    assert right.model.error_flags == MotorErrorFlags.NONE
    assert driver.fault is None and agent.state == "IDLE.MANUAL"
    drive(robot, back_t + 2.5)
    assert all(abs(m.model.speed_radps) > 0.5 for m in (left, right))
    recoveries = [r for r in agent.trace if r.t >= fault_t and r.trigger == "recover" and r.accepted]
    assert len(recoveries) == 1 and recoveries[0].t >= back_t
    assert sum(r.trigger == "fault" and r.accepted for r in agent.trace if r.t >= fault_t) == 1, "no flapping"
