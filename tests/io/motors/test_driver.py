"""The RMD driver drives two emulated motors over a virtual CAN bus on a simulated clock."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace

import can
import pytest

from atemr.clock import SimClock
from atemr.errors import BusError, HardwareError
from atemr.io.motors.driver import MotorState, RmdDriver, WatchdogEvent, _updated
from atemr.io.motors.emulator import RmdMotorEmulator
from atemr.io.motors.model import RmdMotorModel
from atemr.io.motors.rmd_codec import AckReply, MotorErrorFlags, RmdCommand, RmdRequest, Status1Reply, Status2Reply
from atemr.io.motors.rmd_v4 import V4Status1Reply, V4Status2Reply
from atemr.msgs import WheelSpeeds
from atemr.scheduler import Scheduler


@dataclass
class Rig:
    clock: SimClock
    sched: Scheduler
    driver: RmdDriver
    left: RmdMotorEmulator
    right: RmdMotorEmulator
    faults: list[HardwareError]
    watchdog: list[WatchdogEvent]

    def run(self, seconds: float) -> None:
        self.sched.run(duration=seconds)


@pytest.fixture
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    channel = f"motors-{request.node.name}"
    clock = SimClock()
    faults: list[HardwareError] = []
    events: list[WatchdogEvent] = []
    driver = RmdDriver(can.Bus(interface="virtual", channel=channel), on_fault=faults.append,
                       on_watchdog=events.append)
    left = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 1, RmdMotorModel())
    right = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 2, RmdMotorModel(initial_angle_rad=1.0))
    sched = Scheduler(clock)
    sched.add(driver, 50.0)
    sched.add(left, 100.0)
    sched.add(right, 100.0)
    sched.start()
    yield Rig(clock, sched, driver, left, right, faults, events)
    sched.shutdown()
    assert all(bus._is_shutdown for bus in (driver.bus, left.bus, right.bus))


def command_for(rig: Rig, speeds: WheelSpeeds, seconds: float, period: float = 0.1) -> None:
    for _ in range(round(seconds / period)):
        rig.driver.set_speeds(speeds, rig.clock.now())
        rig.run(period)


def test_speed_commands_reach_the_motors_and_feedback_returns(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(5.0, 5.0), 1.0)
    assert rig.left.model.speed_radps == pytest.approx(5.0, abs=0.05)
    assert rig.right.model.speed_radps == pytest.approx(-5.0, abs=0.05)  # mirrored mounting
    feedback = rig.driver.feedback()
    # status 2 carries 1 dps resolution and is one tick old
    assert feedback.left_radps == pytest.approx(5.0, abs=0.1)
    assert feedback.right_radps == pytest.approx(5.0, abs=0.1)
    assert rig.driver.answering and rig.faults == []
    assert rig.driver.states["left"].voltage_v == pytest.approx(24.0)
    assert rig.driver.states["left"].encoder != rig.driver.states["right"].encoder


def test_watchdog_commands_zero_after_half_a_second(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(4.0, 4.0), 0.5)
    assert not rig.driver.watchdog_tripped
    t_last = rig.clock.now() - 0.1
    rig.run(0.38)  # 0.48 s since the last command: still driving
    assert not rig.driver.watchdog_tripped and rig.driver.commanded == WheelSpeeds(4.0, 4.0)
    rig.run(0.1)
    assert rig.driver.watchdog_tripped and rig.driver.watchdog_trips == 1
    assert rig.driver.commanded == WheelSpeeds()
    trip = [e for e in rig.watchdog if e.tripped][-1]
    assert 0.5 < trip.age_s <= 0.52 and trip.t - t_last == pytest.approx(trip.age_s)
    rig.run(1.0)
    assert abs(rig.left.model.speed_radps) < 0.01 and abs(rig.right.model.speed_radps) < 0.01
    assert rig.faults == []  # the watchdog is not a fault
    command_for(rig, WheelSpeeds(1.0, 1.0), 0.5)
    assert not rig.driver.watchdog_tripped and rig.left.model.command_radps == pytest.approx(1.0, abs=1e-3)


def test_silent_motor_stops_both(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(3.0, 3.0), 0.5)
    rig.right.model.unplug()
    with pytest.raises(HardwareError, match=r"right motor .* silent") as info:
        command_for(rig, WheelSpeeds(3.0, 3.0), 1.0)
    assert info.value.critical and info.value.component == "motors"
    assert len(rig.faults) == 1 and rig.faults[0] is info.value
    assert rig.left.model.target_radps == 0.0  # the healthy motor was stopped too
    rig.run(1.0)
    assert abs(rig.left.model.speed_radps) < 0.01
    with pytest.raises(HardwareError):
        rig.driver.check()


def test_injected_error_flag_stops_both(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(2.0, 2.0), 0.5)
    rig.left.model.inject_error(MotorErrorFlags.OVER_TEMPERATURE)
    rig.run(0.3)
    assert rig.driver.fault is not None
    assert "left motor (id 1) reports OVER_TEMPERATURE" in str(rig.driver.fault)
    assert rig.right.model.target_radps == 0.0
    with pytest.raises(HardwareError, match="OVER_TEMPERATURE"):
        rig.driver.set_speeds(WheelSpeeds(1.0, 1.0), rig.clock.now())
    # the cause goes away; clearing the flags over CAN brings the motors back
    rig.left.model.clear_injected()
    rig.driver.clear_motor_errors()
    command_for(rig, WheelSpeeds(1.0, 1.0), 1.0)
    assert rig.driver.fault is None and rig.left.model.error_flags == MotorErrorFlags.NONE
    assert rig.left.model.speed_radps == pytest.approx(1.0, abs=0.02)


def test_recover_clears_the_fault_only_once_both_motors_answer_without_a_flag(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(2.0, 2.0), 0.5)
    assert rig.driver.recover(rig.clock.now()) is None  # nothing latched
    rig.right.model.unplug()
    rig.run(0.5)
    assert rig.driver.fault is not None
    assert rig.driver.recover(rig.clock.now()) == "right motor (id 2) not answering"
    rig.right.model.plug()
    rig.left.model.inject_error(MotorErrorFlags.OVER_TEMPERATURE)
    rig.run(0.3)  # both answer again; the left one's status 1 carries the flag
    assert rig.driver.recover(rig.clock.now()) == "left motor reports OVER_TEMPERATURE"
    rig.run(0.3)  # the CLEAR_ERRORS it sent cannot clear a flag whose cause is still there
    assert rig.driver.recover(rig.clock.now()) == "left motor reports OVER_TEMPERATURE"
    assert rig.driver.fault is not None
    rig.left.model.clear_injected()  # the cause goes; the flag stays latched in the motor until CLEAR_ERRORS
    rig.run(0.3)
    assert rig.left.model.error_flags == MotorErrorFlags.NONE  # cleared by the CLEAR_ERRORS sent above
    assert rig.driver.recover(rig.clock.now()) is None and rig.driver.fault is None
    command_for(rig, WheelSpeeds(1.0, 1.0), 1.0)
    assert rig.left.model.speed_radps == pytest.approx(1.0, abs=0.02)


def test_under_voltage_is_reported(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(1.0, 1.0), 0.3)
    rig.right.model.voltage_v = 16.0
    rig.run(0.3)
    assert "right motor (id 2) reports UNDER_VOLTAGE" in str(rig.driver.fault)


def test_no_motor_at_startup_is_a_fault(request: pytest.FixtureRequest) -> None:
    channel = f"motors-{request.node.name}"
    clock = SimClock()
    with RmdDriver(can.Bus(interface="virtual", channel=channel)) as driver:
        sched = Scheduler(clock)
        sched.add(driver, 50.0)
        sched.run(duration=0.5)
        assert not driver.answering
        with pytest.raises(HardwareError, match="silent"):
            driver.check()


def test_deterministic_runs(request: pytest.FixtureRequest) -> None:
    def once(suffix: str) -> list[tuple[float, float, int]]:
        channel = f"motors-{request.node.name}-{suffix}"
        clock = SimClock()
        driver = RmdDriver(can.Bus(interface="virtual", channel=channel))
        left = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 1)
        right = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 2)
        sched = Scheduler(clock)
        for comp, rate in ((driver, 50.0), (left, 100.0), (right, 100.0)):
            sched.add(comp, rate)
        out = []
        with driver, left, right:
            for k in range(40):
                driver.set_speeds(WheelSpeeds(math.sin(k / 5), math.cos(k / 5)), clock.now())
                sched.run(duration=0.05)
                fb = driver.feedback()
                out.append((fb.left_radps, fb.right_radps, driver.states["left"].encoder))
        return out

    assert once("a") == once("b")


def test_shutdown_stops_motors_and_is_idempotent(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(2.0, 2.0), 0.5)
    rig.driver.shutdown()
    rig.driver.shutdown()
    rig.left.tick(rig.clock.now() + 0.01)
    rig.right.tick(rig.clock.now() + 0.01)
    assert rig.left.model.target_radps == 0.0 and rig.right.model.target_radps == 0.0


def test_send_failure_is_a_critical_bus_error(request: pytest.FixtureRequest) -> None:
    class BrokenBus(can.BusABC):
        def __init__(self) -> None:
            super().__init__(channel="broken")

        def send(self, msg: can.Message, timeout: float | None = None) -> None:
            raise can.CanOperationError("bus-off")

        def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
            return None, False

    faults: list[HardwareError] = []
    driver = RmdDriver(BrokenBus(), on_fault=faults.append)
    driver.set_speeds(WheelSpeeds(1.0, 1.0), 0.0)
    driver.tick(0.0)
    assert isinstance(driver.fault, BusError) and driver.fault.critical and "bus-off" in str(driver.fault)
    driver.shutdown()


def test_emulator_ignores_garbage_and_other_ids(request: pytest.FixtureRequest) -> None:
    channel = f"motors-{request.node.name}"
    with can.Bus(interface="virtual", channel=channel) as host:
        emu = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 1)
        host.send(can.Message(arbitration_id=0x141, data=b"\x55" + bytes(7), is_extended_id=False))
        host.send(can.Message(arbitration_id=0x142, data=b"\x9a" + bytes(7), is_extended_id=False))
        host.send(RmdRequest(1, RmdCommand.MOTOR_RUN).encode())
        emu.tick(0.0)
        assert (emu.ignored, emu.requests) == (1, 1)
        reply = host.recv(timeout=0)
        assert reply is not None and bytes(reply.data) == bytes((0x88, 0, 0, 0, 0, 0, 0, 0))
        assert host.recv(timeout=0) is None
        emu.shutdown()


def test_motor_ids_may_not_collide_with_the_inter_core_protocol() -> None:
    with can.Bus(interface="virtual", channel="motors-collide") as bus:
        with pytest.raises(HardwareError, match="0x150"):
            RmdDriver(bus, left_id=16, right_id=2)
        with pytest.raises(HardwareError, match="0x157"):
            RmdMotorEmulator(bus, 23)


def test_brake_on_off(rig: Rig) -> None:
    from atemr.io.motors.model import MotorMode

    command_for(rig, WheelSpeeds(3.0, 3.0), 0.5)
    rig.driver.brake(rig.clock.now())
    rig.run(0.02)
    assert rig.left.model.target_radps == 0.0 and rig.right.model.target_radps == 0.0
    assert rig.driver.commanded == WheelSpeeds()
    rig.driver.motor_off()
    command_for(rig, WheelSpeeds(2.0, 2.0), 0.3)  # ignored while off
    assert rig.left.model.mode is MotorMode.OFF and rig.right.model.mode is MotorMode.OFF
    rig.driver.motor_on()
    command_for(rig, WheelSpeeds(1.0, 1.0), 1.0)
    assert rig.left.model.speed_radps == pytest.approx(1.0, abs=0.02)


def test_feedback_stays_fresh_after_a_fault(rig: Rig) -> None:
    command_for(rig, WheelSpeeds(4.0, 4.0), 0.5)
    rig.left.model.inject_error(MotorErrorFlags.UNDER_VOLTAGE)
    rig.run(1.5)
    assert rig.driver.fault is not None
    state = rig.driver.states["right"]
    assert state.last_feedback_t == pytest.approx(rig.clock.now(), abs=0.05)
    assert abs(rig.driver.feedback().right_radps) < 0.05  # it stopped, and the feedback says so


def test_emulator_can_leave_the_physics_to_the_simulator() -> None:
    model = RmdMotorModel()
    with can.Bus(interface="virtual", channel="motors-sim-owned") as host:
        emu = RmdMotorEmulator(can.Bus(interface="virtual", channel="motors-sim-owned"), 1, model, steps_model=False)
        host.send(RmdRequest(1, RmdCommand.SPEED_CONTROL, 2.0).encode())
        emu.tick(0.0)
        emu.tick(0.4)  # within the 0.5 s communication timeout
        assert model.command_radps == pytest.approx(2.0, abs=1e-3) and model.speed_radps == 0.0  # not stepped
        model.step(1.0)  # the simulator's step
        host.send(RmdRequest(1, RmdCommand.READ_STATUS_2).encode())
        emu.tick(1.0)
        host.recv(timeout=0)  # the 0xA2 reply
        reply = host.recv(timeout=0)
        assert reply is not None and reply.data[0] == 0x9C
        emu.shutdown()


def test_metres_per_second_helpers() -> None:
    from atemr.io.motors.driver import wheel_speeds_from_mps, wheel_speeds_to_mps

    speeds = wheel_speeds_from_mps(0.5, -0.25, 0.1)
    assert speeds == WheelSpeeds(5.0, -2.5)
    assert wheel_speeds_to_mps(speeds, 0.1) == pytest.approx((0.5, -0.25))
    with pytest.raises(HardwareError, match="wheel radius"):
        wheel_speeds_from_mps(1.0, 1.0, 0.0)


def test_a_reply_updates_the_state_as_replacing_its_fields_would() -> None:
    """`_updated` builds the new state field by field (for speed); this pins it to what `dataclasses.replace` with
    the reply's fields gives, for every kind of reply of both versions, so a field added to `MotorState` (or
    put in another order) cannot be filled from the wrong value."""
    state = MotorState("right", 2, speed_radps=1.5, encoder=77, angle_rad=0.25, current_a=0.5, temperature_c=31,
                       voltage_v=23.9, errors=MotorErrorFlags.UNDER_VOLTAGE, last_reply_t=3.0, last_feedback_t=2.5)
    assert len(fields(MotorState)) == 11  # the constructor calls in `_updated` list all eleven
    s2 = Status2Reply(2, RmdCommand.SPEED_CONTROL, 40, 1.25, 2.0, 1234)
    v4s2 = V4Status2Reply(2, RmdCommand.SPEED_CONTROL, 41, -1.0, 3.0, 0.5)
    s1 = Status1Reply(2, RmdCommand.READ_STATUS_1, 42, 24.5, MotorErrorFlags.OVER_TEMPERATURE)
    v4s1 = V4Status1Reply(2, RmdCommand.READ_STATUS_1, 43, 24.0, MotorErrorFlags.NONE)
    expected = {
        s2: replace(state, last_reply_t=9.0, speed_radps=-s2.speed_radps, current_a=-s2.current_a,
                    temperature_c=40, last_feedback_t=9.0, encoder=1234),
        v4s2: replace(state, last_reply_t=9.0, speed_radps=-v4s2.speed_radps, current_a=-v4s2.current_a,
                      temperature_c=41, last_feedback_t=9.0, angle_rad=-v4s2.angle_rad),
        s1: replace(state, last_reply_t=9.0, temperature_c=42, voltage_v=s1.voltage_v, errors=s1.errors),
        v4s1: replace(state, last_reply_t=9.0, temperature_c=43, voltage_v=v4s1.voltage_v, errors=v4s1.errors),
        AckReply(2, RmdCommand.MOTOR_STOP): replace(state, last_reply_t=9.0),
    }
    for reply, want in expected.items():
        assert _updated(state, reply, -1, 9.0) == want, type(reply).__name__
