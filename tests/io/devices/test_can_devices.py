"""The CAN devices behind the same device interface as the sensors: the motor pair (`RmdDriver`) and the
secondary core (`SecondaryLink`) give the latest reading, subscriptions, a health probe and their identity."""

from __future__ import annotations

import math

import can

from atemr.clock import SimClock
from atemr.io.can.bus import unique_channel
from atemr.io.devices.base import Device
from atemr.io.motors.driver import MotorsReading, RmdDriver
from atemr.io.motors.emulator import RmdMotorEmulator
from atemr.msgs import CliffReadings, WheelSpeeds
from atemr.scheduler import Scheduler
from secondary_core.harness import LinkBench


def test_the_motor_pair_is_a_device() -> None:
    channel = unique_channel("motor-device")
    clock = SimClock()
    driver = RmdDriver(can.Bus(interface="virtual", channel=channel), protocol="v4")
    emulators = [RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), i, protocol="v4") for i in (1, 2)]
    scheduler = Scheduler(clock)
    for part, rate in ((driver, 50.0), (emulators[0], 100.0), (emulators[1], 100.0)):
        scheduler.add(part, rate)
    seen: list[MotorsReading] = []
    driver.subscribe(seen.append)
    assert isinstance(driver, Device)
    scheduler.start()
    try:
        assert driver.latest is None and not driver.health(clock.now()).ok
        for _ in range(10):
            driver.set_speeds(WheelSpeeds(2.0, 2.0), clock.now())
            scheduler.run(duration=0.1)
        assert driver.health(clock.now()).ok and seen and seen[-1] is driver.latest and driver.count == len(seen)
        assert math.isclose(driver.latest.left.speed_radps, 2.0, abs_tol=0.3)
        info = driver.info()
        assert (info.kind, info.driver, info.firmware) == ("motors", "rmd", "protocol v4")
        assert info.model is not None and "RMD-L-7015" in info.model
        emulators[1].model.unplug()  # the right motor goes silent
        scheduler.run(duration=1.0)
        health = driver.health(clock.now())
        assert not health.ok and "right motor (id 2) silent" in health.detail
    finally:
        scheduler.shutdown()


def test_the_secondary_core_is_a_device() -> None:
    bench = LinkBench(cliff=CliffReadings(0.0, 0.05, 0.06, 0.07))
    link = bench.link
    seen: list[CliffReadings] = []
    link.subscribe(seen.append)
    assert isinstance(link, Device)
    try:
        assert not link.health(bench.now).ok and "no heartbeat answer" in link.health(bench.now).detail
        bench.run_until(lambda: link.heartbeat_ok and link.latest is not None, timeout_s=10)
        bench.run(0.5)
        assert link.health(bench.now).ok and seen[-1] == link.latest and link.count == len(seen)
        assert math.isclose(link.latest.front_left_m, 0.05, abs_tol=1e-6)
        assert link.info().kind == "secondary" and link.info().driver == "esp32"
    finally:
        bench.close()
