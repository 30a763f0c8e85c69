"""The battery gauge on the robot: `BatteryGauge` turns the motors' supply-voltage readings (status 1, 0x9A,
which the motor driver polls) into a state of charge (`atemr.skills.battery.BatteryEstimator`) and offers it,
with the configured limits, as a `BatteryStatus`.

It only measures. What the robot does about the charge (warn, go home, stop) is the agent's Monitor's
(``WatchBattery`` in ``trees/agent.yaml``, `atemr.trees.leaves.monitor`), which reads this gauge through the
robot port, so the reactions run with the agent's state, its triggers and its trace like every other one.
Readings the estimator rejects (NaN, 0, impossible jumps) are counted, reported now and then, and never used.
"""

from __future__ import annotations

from collections.abc import Callable

from atemr.domain.status import BatteryStatus
from atemr.io.motors.driver import RmdDriver
from atemr.skills.battery import BatteryEstimator, BatteryParams

#: How often the gauge reads the motors' voltages (the driver polls status 1 every 0.2 s).
RATE_HZ = 2.0
#: Rejected readings reported as an event (the first, then each tenfold): enough to see a loose connector
#: without one event per reading.
REPORTED_REJECTIONS = (1, 10, 100, 1000)


class BatteryGauge:
    """See the module docstring; a scheduler component named ``battery``."""

    name = "battery"

    def __init__(self, params: BatteryParams, driver: RmdDriver, *, event: Callable[[str, str], None]) -> None:
        self.params = params
        self.driver = driver
        self.event = event
        self.estimator = BatteryEstimator(params)

    def status(self) -> BatteryStatus | None:
        """The charge and its limits; None before the first reading the estimator took."""
        latest = self.estimator.latest
        return None if latest is None else self.params.status(latest)

    def forbids_task(self) -> str | None:
        """Why no new task should start now (the routines ask before each run), else None."""
        status = self.status()
        return None if status is None else status.forbids_task()

    def tick(self, now: float) -> None:
        motors = [(s.current_a, s.speed_radps) for s in self.driver.states.values()]
        for state in self.driver.states.values():
            if state.last_reply_t is None:
                continue  # no reply yet: nothing was measured, nothing to reject
            why = self.estimator.update(now, state.voltage_v, motors)
            if why is not None and self.estimator.rejected in REPORTED_REJECTIONS:
                self.event("battery", f"reading rejected ({self.estimator.rejected} so far): {why}")


__all__ = ["RATE_HZ", "BatteryGauge"]
