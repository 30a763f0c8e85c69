"""The RMD's CAN communication-timeout protection: a motor that hears no speed command for ``comm_timeout_s``
stops by itself (docs/testing.md#what-the-robot-promises), says so, and drives again only on a fresh speed command."""

from __future__ import annotations

from collections.abc import Iterator

import can
import pytest

from atemr.errors import HardwareError
from atemr.io.motors.emulator import COMM_TIMEOUT_S, RmdMotorEmulator
from atemr.io.motors.model import MotorMode, RmdMotorModel
from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest

PERIOD = 0.02


@pytest.fixture
def host(request: pytest.FixtureRequest) -> Iterator[can.BusABC]:
    with can.Bus(interface="virtual", channel=f"comm-timeout-{request.node.name}") as bus:
        yield bus


def drain(host: can.BusABC) -> None:
    while host.recv(timeout=0) is not None:
        pass


def run(emu: RmdMotorEmulator, host: can.BusABC, start: float, seconds: float, *,
        command: float | None = None, request: RmdCommand | None = None) -> float:
    """Tick ``emu`` at 50 Hz from ``start`` for ``seconds``; before each tick send ``command`` (a speed) or
    ``request`` (another command), if given. Returns the time of the last tick."""
    t = start
    for k in range(round(seconds / PERIOD)):
        t = start + k * PERIOD
        if command is not None:
            host.send(RmdRequest(1, RmdCommand.SPEED_CONTROL, command).encode())
        elif request is not None:
            host.send(RmdRequest(1, request).encode())
        emu.tick(t)
        drain(host)
    return t


@pytest.fixture
def motor(request: pytest.FixtureRequest, host: can.BusABC) -> Iterator[RmdMotorEmulator]:
    emu = RmdMotorEmulator(can.Bus(interface="virtual", channel=f"comm-timeout-{request.node.name}"), 1)
    yield emu
    emu.shutdown()


def test_the_default_timeout_is_half_a_second(motor: RmdMotorEmulator) -> None:
    assert motor.comm_timeout_s == COMM_TIMEOUT_S == 0.5


def test_a_motor_commanded_every_period_keeps_driving(motor: RmdMotorEmulator, host: can.BusABC) -> None:
    run(motor, host, 0.0, 3.0, command=5.0)
    assert not motor.model.comm_timed_out and motor.comm_timeouts == 0
    assert motor.model.target_radps == pytest.approx(5.0, abs=1e-3)
    assert motor.model.speed_radps == pytest.approx(5.0, abs=0.01)


def test_a_motor_that_hears_nothing_stops_within_the_timeout(motor: RmdMotorEmulator, host: can.BusABC) -> None:
    last = run(motor, host, 0.0, 1.0, command=5.0)  # the last command arrives after the tick at `last`
    t = last
    while motor.model.target_radps != 0.0:
        t += PERIOD
        motor.tick(t)
        assert t - last <= COMM_TIMEOUT_S + 1e-9, "still driving more than 0.5 s after the last command"
    assert t - last >= COMM_TIMEOUT_S - PERIOD - 1e-9  # and not much earlier
    assert motor.model.comm_timed_out and motor.comm_timeouts == 1
    assert motor.model.mode is MotorMode.STOPPED and motor.model.command_radps == 0.0
    run(motor, host, t + PERIOD, 1.0)
    assert abs(motor.model.speed_radps) < 0.01  # braked to rest
    assert motor.comm_timeouts == 1  # tripped once for one silence


def test_status_reads_and_run_do_not_keep_a_motor_driving(motor: RmdMotorEmulator, host: can.BusABC) -> None:
    run(motor, host, 0.0, 1.0, command=5.0)
    t = run(motor, host, 1.0, 0.6, request=RmdCommand.READ_STATUS_2)
    assert motor.model.comm_timed_out and motor.model.target_radps == 0.0
    run(motor, host, t + PERIOD, 0.2, request=RmdCommand.MOTOR_RUN)  # resumes the forgotten (zero) command
    assert motor.model.mode is MotorMode.RUNNING and motor.model.target_radps == 0.0


def test_a_fresh_speed_command_drives_again(motor: RmdMotorEmulator, host: can.BusABC) -> None:
    run(motor, host, 0.0, 1.0, command=5.0)
    t = run(motor, host, 1.0, 0.8)
    assert motor.model.comm_timed_out
    run(motor, host, t + PERIOD, 1.0, command=-3.0)
    assert not motor.model.comm_timed_out and motor.model.mode is MotorMode.RUNNING
    assert motor.model.speed_radps == pytest.approx(-3.0, abs=0.01)


def test_a_slow_emulator_still_stops_on_time(host: can.BusABC, request: pytest.FixtureRequest) -> None:
    # ticked at 10 Hz: the command found at a tick may have arrived just after the previous one, so the silence
    # counts from then and the motor never drives longer than the timeout on one command
    emu = RmdMotorEmulator(can.Bus(interface="virtual", channel=f"comm-timeout-{request.node.name}"), 1)
    try:
        host.send(RmdRequest(1, RmdCommand.SPEED_CONTROL, 4.0).encode())
        emu.tick(0.0)
        emu.tick(0.1)
        drain(host)
        host.send(RmdRequest(1, RmdCommand.SPEED_CONTROL, 4.0).encode())
        emu.tick(0.2)  # arrived in (0.1, 0.2]
        for t in (0.3, 0.4, 0.5):
            emu.tick(t)
            assert emu.model.target_radps == pytest.approx(4.0, abs=1e-3)
        emu.tick(0.6)  # 0.5 s after 0.1
        assert emu.model.target_radps == 0.0 and emu.model.comm_timed_out
    finally:
        emu.shutdown()


def test_the_timeout_is_configurable_and_zero_turns_it_off(host: can.BusABC, request: pytest.FixtureRequest) -> None:
    channel = f"comm-timeout-{request.node.name}"
    off = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 1, comm_timeout_s=0.0)
    short = RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), 2, comm_timeout_s=0.1)
    try:
        for motor_id in (1, 2):
            host.send(RmdRequest(motor_id, RmdCommand.SPEED_CONTROL, 2.0).encode())
        for k in range(100):
            off.tick(k * PERIOD)
            short.tick(k * PERIOD)
            if k == 6:  # 0.12 s
                assert short.model.comm_timed_out
        assert not off.model.comm_timed_out and off.model.target_radps == pytest.approx(2.0, abs=1e-3)
        assert short.model.target_radps == 0.0 and short.comm_timeouts == 1
    finally:
        off.shutdown()
        short.shutdown()


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_a_bad_timeout_is_refused(bad: float) -> None:
    bus = can.Bus(interface="virtual", channel="comm-timeout-bad")
    try:
        with pytest.raises(HardwareError, match="comm_timeout_s"):
            RmdMotorEmulator(bus, 1, comm_timeout_s=bad)
    finally:
        bus.shutdown()


def test_the_model_reports_the_timeout_until_a_speed_command_or_power_up() -> None:
    model = RmdMotorModel()
    model.set_speed(3.0)
    model.step(1.0)
    model.comm_timeout()
    assert model.comm_timed_out and model.target_radps == 0.0 and model.mode is MotorMode.STOPPED
    model.run()  # MOTOR_RUN resumes the forgotten command: zero
    assert model.target_radps == 0.0 and model.comm_timed_out
    model.set_speed(1.0)
    assert not model.comm_timed_out and model.target_radps == 1.0
    model.comm_timeout()
    model.unplug()
    model.plug()
    assert not model.comm_timed_out
