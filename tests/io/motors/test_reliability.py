"""The motors over a damaged link: the driver stops both motors safely and recovers when the link does."""

from __future__ import annotations

import can
import pytest

from atemr.clock import SimClock
from atemr.config import MotorsConfig
from atemr.errors import HardwareError
from atemr.io.can.faults import FaultInjectionBus, FaultPlan
from atemr.io.motors.driver import RmdDriver
from atemr.io.motors.emulator import RmdMotorEmulator
from atemr.msgs import WheelSpeeds
from atemr.scheduler import Scheduler


def build(channel: str, plan: FaultPlan) -> tuple[SimClock, Scheduler, RmdDriver, FaultInjectionBus,
                                                  list[RmdMotorEmulator]]:
    clock = SimClock()
    link = FaultInjectionBus(can.Bus(interface="virtual", channel=channel), plan, clock)
    driver = RmdDriver.from_config(link, MotorsConfig())
    motors = [RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), i) for i in (1, 2)]
    sched = Scheduler(clock)
    sched.add(driver, MotorsConfig().rate_hz)
    for m in motors:
        sched.add(m, 100.0)
    sched.start()
    return clock, sched, driver, link, motors


def drive(clock: SimClock, sched: Scheduler, driver: RmdDriver, seconds: float, speed: float = 3.0) -> None:
    for _ in range(round(seconds / 0.1)):
        driver.set_speeds(WheelSpeeds(speed, speed), clock.now())
        sched.run(duration=0.1)


def test_lossy_link_keeps_driving() -> None:
    plan = FaultPlan(drop=0.05, duplicate=0.05, delay=0.05, delay_s=0.03, reorder=0.05, seed=11)
    clock, sched, driver, link, motors = build("reliability-lossy", plan)
    try:
        drive(clock, sched, driver, 3.0)
        assert driver.fault is None
        assert motors[0].model.speed_radps == pytest.approx(3.0, abs=0.05)
        stats = link.stats["send"]
        assert stats.dropped and stats.duplicated and stats.delayed and stats.reordered
    finally:
        sched.shutdown()


def test_outage_stops_both_motors_and_recovery_restarts_them() -> None:
    clock, sched, driver, _link, motors = build("reliability-outage", FaultPlan(outages=((2.0, 3.0),)))
    try:
        drive(clock, sched, driver, 2.0)
        assert motors[0].model.speed_radps == pytest.approx(3.0, abs=0.05)
        with pytest.raises(HardwareError, match="silent"):
            drive(clock, sched, driver, 1.0)
        # the stop sent at the fault was lost with the link; the driver repeats it, so once the link is back
        # (t = 3 s) the motors stop even before anyone clears the fault
        assert motors[0].model.target_radps == pytest.approx(3.0, abs=0.01)
        sched.run(until=3.25)
        assert driver.fault is not None
        assert motors[0].model.target_radps == 0.0 and motors[1].model.target_radps == 0.0
        # the link is back: clearing the fault resumes control, and the motors answer again
        driver.clear_motor_errors()
        drive(clock, sched, driver, 1.0, speed=2.0)
        assert driver.fault is None and driver.answering
        assert motors[0].model.speed_radps == pytest.approx(2.0, abs=0.05)
        assert motors[1].model.speed_radps == pytest.approx(-2.0, abs=0.05)
    finally:
        sched.shutdown()


def test_corrupted_replies_are_counted_not_trusted() -> None:
    clock, sched, driver, link, _motors = build("reliability-corrupt", FaultPlan(corrupt=0.2, seed=5))
    try:
        link.direction = "recv"
        drive(clock, sched, driver, 2.0)
        assert link.stats["recv"].corrupted > 0
        # a corrupted reply either fails to decode or carries a wrong value; a flipped error-flag bit
        # (or a wrong temperature) may legitimately stop the motors, which is the safe outcome
        assert driver.bad_frames > 0 or driver.fault is not None
    finally:
        sched.shutdown()
