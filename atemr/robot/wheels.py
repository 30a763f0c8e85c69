"""`WheelOdometryFeed`: the motor driver's measured wheel speeds to localization, at the odometry rate.

A scheduler component rather than a bare ticker because more than localization wants each sample exactly as
localization got it: the recorder subscribes, so a replay feeds localization the same samples at the same
times (`atemr.robot.replay`).
"""

from __future__ import annotations

from collections.abc import Callable

from atemr.io.motors.driver import RmdDriver
from atemr.msgs import WheelSpeeds
from atemr.skills.localization.pipeline import LocalizationPipeline

WheelListener = Callable[[float, WheelSpeeds], None]


class WheelOdometryFeed:
    """Each tick: ``driver.feedback()`` to ``localization.on_wheels``, then to every subscriber."""

    name = "wheel_odometry"

    def __init__(self, driver: RmdDriver, localization: LocalizationPipeline) -> None:
        self.driver = driver
        self.localization = localization
        self._listeners: list[WheelListener] = []

    def subscribe(self, listener: WheelListener) -> None:
        self._listeners.append(listener)

    def tick(self, now: float) -> None:
        wheels = self.driver.feedback()
        self.localization.on_wheels(now, wheels)
        for listener in self._listeners:
            listener(now, wheels)
