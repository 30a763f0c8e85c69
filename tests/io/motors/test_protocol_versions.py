"""The driver and the emulated motors speak V1.61 or V4.2 over python-can's virtual bus, as configured."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import can
import pytest

from atemr.clock import SimClock
from atemr.config import MotorsConfig
from atemr.errors import HardwareError, ProtocolError
from atemr.io.motors.driver import RmdDriver, check_motor_ids
from atemr.io.motors.emulator import RmdMotorEmulator
from atemr.io.motors.model import MotorMode, RmdMotorModel
from atemr.io.motors.rmd_codec import MotorErrorFlags, RmdCommand, RmdRequest
from atemr.msgs import WheelSpeeds
from atemr.scheduler import Scheduler


@dataclass
class Rig:
    clock: SimClock
    sched: Scheduler
    driver: RmdDriver
    left: RmdMotorEmulator
    right: RmdMotorEmulator
    sniffer: can.BusABC
    faults: list[HardwareError]

    def run(self, seconds: float) -> None:
        self.sched.run(duration=seconds)

    def command_for(self, speeds: WheelSpeeds, seconds: float, period: float = 0.1) -> None:
        for _ in range(round(seconds / period)):
            self.driver.set_speeds(speeds, self.clock.now())
            self.run(period)

    def traffic(self) -> list[tuple[int, int]]:
        """(ID, command byte) of every frame on the bus since the last call."""
        seen = []
        while (msg := self.sniffer.recv(timeout=0)) is not None:
            seen.append((msg.arbitration_id, msg.data[0]))
        return seen


def build(channel: str, protocol: str) -> Rig:
    clock = SimClock()
    faults: list[HardwareError] = []
    driver = RmdDriver.from_config(can.Bus(interface="virtual", channel=channel), MotorsConfig(), protocol=protocol,
                                   on_fault=faults.append)
    left = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 1, protocol=protocol)
    right = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 2,
                             RmdMotorModel(initial_angle_rad=1.0), protocol=protocol)
    sched = Scheduler(clock)
    sched.add(driver, 50.0)
    sched.add(left, 100.0)
    sched.add(right, 100.0)
    sched.start()
    return Rig(clock, sched, driver, left, right, can.Bus(interface="virtual", channel=channel), faults)


@pytest.fixture(params=["v1", "v4"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    made = build(f"versions-{request.node.name}", request.param)
    yield made
    made.sched.shutdown()
    made.sniffer.shutdown()


@pytest.fixture
def v4_rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    made = build(f"versions-{request.node.name}", "v4")
    yield made
    made.sched.shutdown()
    made.sniffer.shutdown()


def test_both_versions_drive_and_report(rig: Rig) -> None:
    rig.command_for(WheelSpeeds(5.0, 5.0), 1.0)
    assert rig.left.model.speed_radps == pytest.approx(5.0, abs=0.05)
    assert rig.right.model.speed_radps == pytest.approx(-5.0, abs=0.05)
    feedback = rig.driver.feedback()
    assert feedback.left_radps == pytest.approx(5.0, abs=0.1) and feedback.right_radps == pytest.approx(5.0, abs=0.1)
    assert rig.driver.answering and rig.faults == [] and rig.driver.bad_frames == 0
    left = rig.driver.states["left"]
    assert left.voltage_v == pytest.approx(24.0) and left.temperature_c == 25
    ids = {can_id for can_id, _ in rig.traffic()}
    if rig.driver.protocol.version == "v4":
        assert ids == {0x141, 0x142, 0x241, 0x242}  # requests on 0x140 + id, replies on 0x240 + id
        rig.command_for(WheelSpeeds(), 1.0)  # standing still, the last reply's angle is the motor's
        angle = rig.driver.states["left"].angle_rad
        assert angle == pytest.approx(rig.left.model.position_rad, abs=math.radians(0.5) + 1e-3)  # 1° resolution
        assert left.encoder == 0
    else:
        assert ids == {0x141, 0x142}
        assert left.angle_rad is None and left.encoder != rig.driver.states["right"].encoder


def test_v4_low_voltage_latches_a_fault_naming_it_and_clears_by_itself(v4_rig: Rig) -> None:
    rig = v4_rig
    rig.command_for(WheelSpeeds(2.0, 2.0), 0.5)
    rig.right.model.voltage_v = 16.0  # below the motor's 18 V: V4.2 error state 0x0004
    rig.run(0.3)
    fault = rig.driver.fault
    assert fault is not None and rig.faults == [fault] and fault.critical
    assert "right motor (id 2) reports UNDER_VOLTAGE (V4.2 0x0004 low voltage)" in str(fault)
    assert rig.left.model.target_radps == 0.0  # both stopped
    assert rig.driver.recover(rig.clock.now()) == "right motor reports UNDER_VOLTAGE (V4.2 0x0004 low voltage)"
    rig.right.model.voltage_v = 24.0  # the supply recovers: a level-2 error clears in the motor by itself
    rig.run(0.3)
    assert rig.right.model.error_flags == MotorErrorFlags.NONE
    assert rig.driver.recover(rig.clock.now()) is None and rig.driver.fault is None
    rig.command_for(WheelSpeeds(1.0, 1.0), 1.0)
    assert rig.right.model.speed_radps == pytest.approx(-1.0, abs=0.02)
    sent = {command for can_id, command in rig.traffic() if can_id in (0x141, 0x142)}
    assert RmdCommand.CLEAR_ERRORS not in sent and RmdCommand.MOTOR_RUN not in sent  # V4.2 has neither


def test_v4_level_one_error_needs_a_system_reset(v4_rig: Rig) -> None:
    rig = v4_rig
    rig.command_for(WheelSpeeds(2.0, 2.0), 0.5)
    rig.left.model.inject_error(MotorErrorFlags.MOTOR_STALL)
    rig.run(0.3)
    assert "left motor (id 1) reports MOTOR_STALL (V4.2 0x0002 motor stall)" in str(rig.driver.fault)
    rig.left.model.clear_injected()  # the load is freed, but a stall stays latched in the motor
    rig.run(0.5)
    why = rig.driver.recover(rig.clock.now())
    assert why is not None and "needs a check and then a system reset (0x76)" in why
    assert rig.left.model.error_flags == MotorErrorFlags.MOTOR_STALL
    rig.traffic()
    rig.driver.system_reset()  # the operator's decision
    rig.run(0.3)
    assert (0x141, RmdCommand.SYSTEM_RESET) in rig.traffic()
    assert rig.left.model.error_flags == MotorErrorFlags.NONE
    assert rig.driver.recover(rig.clock.now()) is None
    rig.command_for(WheelSpeeds(1.0, 1.0), 1.0)
    assert rig.left.model.speed_radps == pytest.approx(1.0, abs=0.02)


def test_v1_clears_flags_with_clear_errors_and_has_no_system_reset(request: pytest.FixtureRequest) -> None:
    rig = build(f"versions-{request.node.name}", "v1")
    try:
        rig.command_for(WheelSpeeds(2.0, 2.0), 0.5)
        rig.left.model.inject_error(MotorErrorFlags.OVER_TEMPERATURE)
        rig.run(0.3)
        rig.left.model.clear_injected()
        rig.run(0.3)
        assert rig.left.model.error_flags == MotorErrorFlags.OVER_TEMPERATURE  # V1.61 keeps it until 0x9B
        assert rig.driver.recover(rig.clock.now()) == "left motor reports OVER_TEMPERATURE"
        rig.run(0.3)
        assert (0x141, RmdCommand.CLEAR_ERRORS) in rig.traffic()
        assert rig.driver.recover(rig.clock.now()) is None
        with pytest.raises(HardwareError, match=r"V1\.61, which has no system reset"):
            rig.driver.system_reset()
    finally:
        rig.sched.shutdown()
        rig.sniffer.shutdown()


def test_motor_on_after_off(rig: Rig) -> None:
    rig.command_for(WheelSpeeds(2.0, 2.0), 0.5)
    rig.driver.motor_off()
    rig.command_for(WheelSpeeds(2.0, 2.0), 0.3)  # ignored while off
    assert rig.left.model.mode is MotorMode.OFF
    rig.traffic()
    rig.driver.motor_on()
    rig.command_for(WheelSpeeds(1.0, 1.0), 1.0)
    assert rig.left.model.speed_radps == pytest.approx(1.0, abs=0.02)
    run_frames = {f for f in rig.traffic() if f[1] == RmdCommand.MOTOR_RUN}  # V1.61: request and its echo
    assert run_frames == (set() if rig.driver.protocol.version == "v4" else {(0x141, 0x88), (0x142, 0x88)})


def test_v4_emulator_ignores_v1_only_commands_and_answers_on_0x240(request: pytest.FixtureRequest) -> None:
    channel = f"versions-{request.node.name}"
    with can.Bus(interface="virtual", channel=channel) as host:
        emu = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 1, protocol="v4")
        host.send(RmdRequest(1, RmdCommand.MOTOR_RUN).encode())
        host.send(RmdRequest(1, RmdCommand.CLEAR_ERRORS).encode())
        host.send(RmdRequest(1, RmdCommand.READ_STATUS_1).encode())
        emu.tick(0.0)
        assert (emu.ignored, emu.requests) == (2, 1)
        reply = host.recv(timeout=0)
        assert reply is not None and reply.arbitration_id == 0x241 and reply.data[0] == 0x9A
        assert int.from_bytes(reply.data[4:6], "little") == 240  # 24.0 V at bytes 4-5
        assert host.recv(timeout=0) is None
        emu.shutdown()


def test_ids_are_checked_per_version() -> None:
    check_motor_ids((1, 2), component="motors", protocol="v4")
    with pytest.raises(HardwareError, match="0x150"):
        check_motor_ids((16,), component="motors", protocol="v4")  # its requests still use 0x150
    with can.Bus(interface="virtual", channel="versions-ids") as bus:
        with pytest.raises(HardwareError, match="0x157"):
            RmdMotorEmulator(bus, 23, protocol="v4")
        with pytest.raises(ProtocolError, match="unknown RMD protocol version 'v3'"):
            RmdDriver(bus, protocol="v3", close_bus=False)
