"""Whole-robot fault scenarios (`build_robot` in simulation): each ends with both motors at zero and the agent
in ERROR with the error classified and the component named; recovery to IDLE where the cause goes away.

In every scenario the operator holds "forward" on the joystick while the fault happens, so "the motors stop"
is a real claim, not the idle robot's zero. The dashboard's state says why the robot is stopped (``stop_cause``,
which the carer reads in plain words), as each fault really reaches it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import can
import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.errors import AtemrError, HardwareError
from atemr.fsm.machine import TransitionRecord
from atemr.io.can.bus import unique_channel
from atemr.io.motors.rmd_codec import MotorErrorFlags
from atemr.msgs import Twist
from atemr.robot import build_robot
from atemr.robot.core import Robot
from atemr.robot.gateway import RobotGatewayImpl

BOOTED_S = 7.0  # the agent is in IDLE.MANUAL and the heartbeat established by then
FORWARD = Twist(0.2, 0.0)


@dataclass
class Entered:
    """The agent entered ERROR: when, why, and the error it will classify."""

    t: float
    reason: str
    error: AtemrError | None


class Harness:
    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.agent: Any = robot.components["agent"]
        self.inputs = robot.parts.inputs
        self.gateway = RobotGatewayImpl(robot)  # what the dashboard shows
        self.emulators = [robot.components["left_motor_emulator"], robot.components["right_motor_emulator"]]
        self.errors: list[Entered] = []
        self.records: list[TransitionRecord] = []
        self.agent.listeners.append(self._on_transition)

    def _on_transition(self, record: TransitionRecord) -> None:
        self.records.append(record)
        if record.accepted and record.dest == "ERROR":
            self.errors.append(Entered(record.t, record.reason, self.agent.context.error))

    def drive(self, until: float, twist: Twist = FORWARD) -> None:
        """The operator holds ``twist`` (resent at 10 Hz, as the page does) until ``until``."""
        t = self.robot.clock.now()
        while t < until - 1e-9:
            self.inputs.operate(twist, t)
            self.robot.run(until=min(until, t + 0.1))
            t = self.robot.clock.now()

    def stop_cause(self) -> str | None:
        """Why the dashboard says the robot is held stopped."""
        return self.gateway.state()["stop_cause"]

    def targets(self) -> list[float]:
        return [m.model.target_radps for m in self.emulators]

    def speeds(self) -> list[float]:
        return [m.model.speed_radps for m in self.emulators]

    def moving(self) -> bool:
        return all(abs(s) > 0.5 for s in self.speeds())

    def stopped(self) -> bool:
        """Both commanded to zero, and every motor with output braked to a standstill (an unpowered or
        self-protecting motor has its output off and coasts: nothing can brake it)."""
        return self.targets() == [0.0, 0.0] and all(abs(m.model.speed_radps) < 0.05 for m in self.emulators
                                                    if m.model.output_enabled)


@pytest.fixture
def harness(tmp_path: Any) -> Iterator[Harness]:
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("faults"),
                                                "sim.seed": 3, "secondary.portal_serve": False, "ui.enabled": False})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        h = Harness(robot)
        robot.run(until=BOOTED_S)
        assert h.agent.state == "IDLE.MANUAL"
        h.drive(BOOTED_S + 1.0)
        assert h.moving(), h.speeds()  # the operator really drives before the fault
        assert h.stop_cause() is None
        yield h
        h.gateway.close()


def stop_time(h: Harness, fault_t: float, limit_s: float) -> float:
    """Drive on (the operator keeps pressing) until both motors are commanded to zero (the stop has reached
    them); the time it took. Then, 0.5 s later, every powered motor must stand still (it brakes with τ 0.08 s)."""
    while h.robot.clock.now() < fault_t + limit_s:
        h.drive(h.robot.clock.now() + 0.02)
        if h.targets() == [0.0, 0.0]:
            took = h.robot.clock.now() - fault_t
            h.drive(h.robot.clock.now() + 0.5)
            assert h.stopped(), f"motors commanded to zero but still turning 0.5 s later: {h.speeds()}"
            return took
    raise AssertionError(f"motors not stopped {limit_s} s after the fault: targets {h.targets()}, speeds {h.speeds()}")


def first_error(h: Harness, since: float) -> Entered:
    errors = [e for e in h.errors if e.t >= since]
    assert errors, f"the agent never entered ERROR: {[(r.source, r.dest, r.reason) for r in h.records[-5:]]}"
    return errors[0]


def classified(h: Harness, since: float) -> str:
    """How the ERROR state classified its error: 'recover' (non-critical) or 'escalate' (critical).

    A non-critical error whose cause lasts (a motor still unplugged, the heartbeat still lost) holds ERROR until
    the cause is gone, so while it lasts the verdict is the ERROR tree's: ClassifyError succeeded (recover once
    the cause clears) and the agent waits in ERROR."""
    verdicts = [r.trigger for r in h.records if r.t >= since and r.source == "ERROR" and r.accepted
                and r.trigger in ("recover", "escalate")]
    tree = h.agent.tree if not verdicts and h.agent.state == "ERROR" else None
    if tree is not None and any(type(n).__name__ == "ClassifyError" and n.status.name == "SUCCESS"
                                for n in tree.iterate()):
        return "recover"
    assert verdicts, "the ERROR state never classified the error"
    return verdicts[0]


# -- heartbeat loss ------------------------------------------------------------------------------------------------
def silence_secondary_core(h: Harness) -> Callable[[], None]:
    board = h.robot.components["secondary_core"]
    tick = board.tick
    board.tick = lambda now: None  # type: ignore[method-assign]

    def restore() -> None:
        board.tick = tick  # type: ignore[method-assign]

    return restore


def test_heartbeat_loss_stops_the_motors_and_enters_error_then_recovers(harness: Harness) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    restore = silence_secondary_core(h)
    # the silent board also stops sending the IR cliff frames, and missing cliff readings stop the base first;
    # the 0x157 watchdog (2 s, then a safety stop that bypasses the ramp) is the backstop
    took = stop_time(h, fault_t, 2.5)
    assert took <= 2.3, took
    h.drive(fault_t + 2.5)
    entered = first_error(h, fault_t)
    assert "heartbeat" in entered.reason and "secondary_core" in entered.reason
    assert entered.error is not None and not entered.error.critical
    assert classified(h, fault_t) == "recover"
    assert h.stop_cause() == "heartbeat"
    h.drive(fault_t + 4.0)
    assert h.stopped()  # the operator still presses forward: nothing moves without the heartbeat
    restore()
    back_t = h.robot.clock.now()
    h.drive(back_t + 2.0)
    assert h.agent.state == "IDLE.MANUAL"
    assert not [e for e in h.errors if e.t > back_t + 1.0]
    h.drive(back_t + 3.0)
    assert h.moving(), "the operator drives again once the heartbeat is back"


def test_dropped_heartbeat_frames_alone_stop_the_motors_after_two_seconds(harness: Harness) -> None:
    """Only 0x157 is lost (the board still sends its IR frames): the heartbeat watchdog is what stops the base."""
    h = harness
    link = h.robot.components["secondary_link"]
    recv = link.bus.recv

    def without_heartbeat(timeout: float | None = None) -> can.Message | None:
        while (frame := recv(timeout=timeout)) is not None and frame.arbitration_id == 0x157:
            pass
        return frame

    link.bus.recv = without_heartbeat
    fault_t = h.robot.clock.now()
    took = stop_time(h, fault_t, 3.0)
    # 2 s after the last valid exchange (up to one heartbeat period before the drop), then the safety stop
    # bypasses the ramp: nothing else stopped the base earlier
    assert 1.0 <= took <= 2.3, took
    h.drive(fault_t + 3.0)
    entered = first_error(h, fault_t)
    assert "heartbeat" in entered.reason and "secondary_core" in entered.reason, entered.reason
    assert h.stop_cause() == "heartbeat"
    link.bus.recv = recv
    back_t = h.robot.clock.now()
    h.drive(back_t + 3.0)
    assert h.agent.state == "IDLE.MANUAL" and h.moving(), (h.agent.state, h.speeds())


def test_a_silent_secondary_core_is_told_as_quiet_floor_sensors_then_lost_contact_never_as_stairs(
        harness: Harness) -> None:
    """Its IR frames stop first, and the cliff stop holds the base for want of readings: the carer reads that the
    floor sensors went quiet (not that a drop is under the robot), then, 2 s on, that the cores lost contact."""
    h = harness
    fault_t = h.robot.clock.now()
    silence_secondary_core(h)
    causes: list[str | None] = []
    while h.robot.clock.now() < fault_t + 3.0:
        h.drive(h.robot.clock.now() + 0.1)
        if not causes or causes[-1] != h.stop_cause():
            causes.append(h.stop_cause())
    assert causes == [None, "floor_sensors", "heartbeat"], causes


def test_heartbeat_loss_keeps_the_agent_in_error_while_it_lasts(harness: Harness) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    silence_secondary_core(h)
    h.drive(fault_t + 2.5)
    states = []
    for _ in range(20):
        h.drive(h.robot.clock.now() + 0.1)
        states.append(h.agent.state)
    assert set(states) == {"ERROR"}, states


# -- one motor silent, a motor error flag ------------------------------------------------------------------------
def test_a_silent_motor_stops_both_and_enters_error_naming_it(harness: Harness) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    h.emulators[0].model.unplug()
    took = stop_time(h, fault_t, 1.0)
    assert took <= 0.5, took
    entered = first_error(h, fault_t)
    assert "left motor" in entered.reason and "silent" in entered.reason, entered.reason
    assert entered.error is not None and "left_motor" in entered.reason
    assert classified(h, fault_t) == "recover"
    h.drive(fault_t + 3.0)
    assert h.targets() == [0.0, 0.0]  # the right motor, still powered, is held at zero too
    assert h.stop_cause() == "motor"
    assert h.robot.parts.driver.fault is not None


def test_an_over_temperature_flag_stops_both_and_enters_error_naming_it(harness: Harness) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    h.emulators[1].model.inject_error(MotorErrorFlags.OVER_TEMPERATURE)
    took = stop_time(h, fault_t, 1.0)
    assert took <= 0.5, took
    entered = first_error(h, fault_t)
    assert "right motor" in entered.reason and "OVER_TEMPERATURE" in entered.reason, entered.reason
    assert classified(h, fault_t) == "recover"
    h.drive(fault_t + 3.0)
    assert h.stopped() and h.stop_cause() == "motor"


def test_a_silent_motor_holds_error_until_it_answers_then_the_robot_drives_again(harness: Harness) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    h.emulators[0].model.unplug()
    h.drive(fault_t + 3.0)
    assert h.agent.state == "ERROR", h.agent.state
    h.emulators[0].model.plug()
    h.drive(fault_t + 6.0)
    assert h.agent.state == "IDLE.MANUAL"
    assert h.moving(), h.speeds()


# -- the CAN interface itself failing ---------------------------------------------------------------------------
def break_bus(h: Harness, what: str) -> Callable[[], None]:
    bus = h.robot.parts.driver.bus
    original = getattr(bus, what)

    def fail(*args: object, **kwargs: object) -> None:
        raise can.CanOperationError(f"{what}: bus-off (simulated)")

    setattr(bus, what, fail)

    def restore() -> None:
        setattr(bus, what, original)

    return restore


@pytest.mark.parametrize("side", ["send", "recv"])
def test_a_failing_can_interface_enters_error_naming_the_motors(harness: Harness, side: str) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    break_bus(h, side)
    h.drive(fault_t + 1.0)
    entered = first_error(h, fault_t)
    assert "motors" in entered.reason and "bus-off" in entered.reason, entered.reason
    word = "send" if side == "send" else "receive"
    assert f"CAN {word} failed" in entered.reason, entered.reason
    assert classified(h, fault_t) == "recover"
    # the driver keeps zero as its command and no further speed frame goes out
    assert h.robot.parts.driver.commanded.left_radps == 0.0
    assert h.robot.parts.driver.fault is not None
    if side == "recv":  # the send side still works: the stop reached the motors
        assert h.stopped()


def test_a_bus_off_primary_still_stops_the_motors(harness: Harness) -> None:
    h = harness
    fault_t = h.robot.clock.now()
    break_bus(h, "send")
    stop_time(h, fault_t, 1.0)


# -- the CAN bus under its supervisor (one receive side for the driver and the link) -----------------------------
def bus_error(entered: Entered) -> HardwareError:
    """The error the agent classifies names the CAN bus, not the motors that went silent behind it."""
    assert entered.reason.startswith("can_bus: "), entered.reason
    error = entered.error
    assert isinstance(error, HardwareError) and error.component == "can_bus", error
    return error


def bus_off_switch(robot: Robot, monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """The robot's CAN controller reports bus-off through python-can's ``bus.state`` while the returned flag's
    one item is True (only the supervised bus does)."""
    supervised = robot.components["can_bus"].bus  # type: ignore[attr-defined]
    off = [False]
    monkeypatch.setattr(type(supervised), "state", property(
        lambda bus: can.BusState.ERROR if bus is supervised and off[0] else can.BusState.ACTIVE))
    return off


def test_bus_off_stops_both_motors_and_enters_error_naming_the_bus_until_it_is_back(
        harness: Harness, monkeypatch: pytest.MonkeyPatch) -> None:
    h = harness
    off = bus_off_switch(h.robot, monkeypatch)
    fault_t = h.robot.clock.now()
    off[0] = True
    took = stop_time(h, fault_t, 1.0)
    assert took <= 0.1, took  # a safety stop: the next control tick, no ramp
    error = bus_error(first_error(h, fault_t))
    assert "bus-off" in str(error) and not error.critical
    assert classified(h, fault_t) == "recover"
    h.drive(fault_t + 3.0)
    assert h.agent.state == "ERROR" and h.stopped()  # held while the bus is off; the operator still presses
    assert h.stop_cause() == "bus"
    off[0] = False
    back_t = h.robot.clock.now()
    h.drive(back_t + 0.8)
    assert h.agent.state == "ERROR"  # the bus must stay good for the supervisor's settle_s (1 s) first
    h.drive(back_t + 2.0)
    assert h.agent.state == "IDLE.MANUAL", [(r.source, r.dest, r.reason) for r in h.records[-5:]]
    assert not [e for e in h.errors if e.t > back_t]
    h.drive(back_t + 3.0)
    assert h.moving(), h.speeds()


def test_a_bus_off_while_in_error_for_a_motor_is_handled_once_the_motor_is_back(
        harness: Harness, monkeypatch: pytest.MonkeyPatch) -> None:
    """The bus fails while the agent waits in ERROR for a silent motor: back from that, the bus is a fault of its
    own, so its recovery runs and its stop is released when it works again (it was held in IDLE for good)."""
    h = harness
    off = bus_off_switch(h.robot, monkeypatch)
    fault_t = h.robot.clock.now()
    h.emulators[0].model.unplug()
    h.drive(fault_t + 1.0)
    assert h.agent.state == "ERROR" and h.stop_cause() == "motor"
    h.emulators[0].model.plug()
    off[0] = True
    h.drive(fault_t + 3.0)
    assert h.stop_cause() == "bus" and h.agent.state == "ERROR"
    bus_error(h.errors[-1])
    off[0] = False
    back_t = h.robot.clock.now()
    h.drive(back_t + 2.0)
    assert h.agent.state == "IDLE.MANUAL" and h.stop_cause() is None, (h.agent.state, h.stop_cause())
    h.drive(back_t + 3.0)
    assert h.moving(), h.speeds()


def test_a_dead_receive_side_stops_both_motors_and_enters_error_naming_the_bus(
        harness: Harness, monkeypatch: pytest.MonkeyPatch) -> None:
    h = harness
    supervised = h.robot.components["can_bus"].bus  # type: ignore[attr-defined]

    def dead(timeout: float | None = None) -> can.Message | None:
        raise can.CanOperationError("controller gone (simulated)")

    fault_t = h.robot.clock.now()
    monkeypatch.setattr(supervised, "recv", dead)
    took = stop_time(h, fault_t, 1.0)
    assert took <= 0.1, took
    error = bus_error(first_error(h, fault_t))
    assert "receive failed: controller gone" in str(error) and not error.critical
    assert classified(h, fault_t) == "recover"
    h.drive(fault_t + 1.5)
    # nothing is received, so the motors went silent too: the driver latched that as well, the bus stays the cause
    assert h.agent.state == "ERROR" and h.robot.parts.driver.fault is not None and h.stopped()
    assert h.stop_cause() == "bus"  # what the carer reads: the bus to mend, not a motor
    monkeypatch.undo()
    back_t = h.robot.clock.now()
    h.drive(back_t + 2.5)
    assert h.agent.state == "IDLE.MANUAL", [(r.source, r.dest, r.reason) for r in h.records[-5:]]
    assert h.robot.parts.driver.fault is None  # both latched faults cleared, not only the bus's
    h.drive(back_t + 3.5)
    assert h.moving(), h.speeds()


def test_a_failing_listener_on_the_bus_is_an_error_naming_the_bus_while_it_fails(harness: Harness) -> None:
    h = harness
    failing = [True]

    def tap(msg: can.Message) -> None:  # e.g. a diagnostic listener with a bug
        if failing[0] and msg.arbitration_id == 0x157:
            raise RuntimeError("tap bug")

    fault_t = h.robot.clock.now()
    h.robot.components["can_bus"].add_listener(tap)  # type: ignore[attr-defined]
    stop_time(h, fault_t, 1.0)
    error = bus_error(first_error(h, fault_t))
    assert "listener failed" in str(error) and "tap bug" in str(error)
    states = []
    for _ in range(20):  # fails on every 0x157 answer (2 Hz): held in ERROR, no flapping back to IDLE
        h.drive(h.robot.clock.now() + 0.1)
        states.append(h.agent.state)
    assert set(states) == {"ERROR"} and h.stopped(), states
    assert len([e for e in h.errors if e.t >= fault_t]) == 1
    failing[0] = False
    back_t = h.robot.clock.now()
    h.drive(back_t + 2.0)
    assert h.agent.state == "IDLE.MANUAL"
    h.drive(back_t + 3.0)
    assert h.moving(), h.speeds()
