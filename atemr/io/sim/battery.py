"""The simulated robot's battery: drained by the motors' power and the electronics' base load, charged at the
dock, and seen by the robot the way the real one is: as the supply voltage each motor measures and reports in
its status-1 reply (0x9A), sagging under load.

Charging is a time at the dock (``sim.battery_charge_s``: empty to full), as a carer knows the robot's charger
("three hours on the dock fills it"): while the robot stands within `DOCK_RADIUS_M` of the dock place, the
charger carries the robot's load and fills the pack at ``capacity_wh / charge_s``, so an hour on the dock adds
the same share whatever the robot draws there. Off the dock the pack only drains.

The truth (``percent``, the energy left) is kept here for tests; the robot never reads it, it estimates the
charge from the motors' replies (`atemr.skills.battery.BatteryEstimator`). The pack's true internal resistance
(``internal_ohm``) need not be the one the estimator assumes, as on a real robot.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Protocol

from atemr.msgs import Pose2D
from atemr.skills.battery import BatteryParams

#: How close to the dock's pose the robot must stand to charge, metres.
DOCK_RADIUS_M = 0.3


class SuppliedMotor(Protocol):
    """A motor model as the battery sees it: its current and speed, and the supply voltage it will report."""

    voltage_v: float

    @property
    def current_a(self) -> float: ...

    @property
    def speed_radps(self) -> float: ...


class SimBattery:
    """The pack (see the module docstring); a scheduler component named ``sim.battery``."""

    name = "sim.battery"

    def __init__(self, params: BatteryParams, motors: Sequence[SuppliedMotor], *, capacity_wh: float,
                 percent: float = 100.0, base_load_w: float = 15.0, charge_s: float = 10_800.0,
                 internal_ohm: float = 0.12, pose: Callable[[], Pose2D] | None = None,
                 dock: Callable[[], Pose2D | None] = lambda: None) -> None:
        self.params = params
        self.motors = list(motors)
        self.capacity_wh = capacity_wh
        self.energy_wh = capacity_wh * min(100.0, max(0.0, percent)) / 100.0
        self.base_load_w = base_load_w
        self.charge_s = charge_s
        self.internal_ohm = internal_ohm
        self.pose = pose
        self.dock = dock
        self.charging = False
        self.current_a = 0.0
        self.terminal_v = params.voltage_at(self.percent)
        self._last: float | None = None
        self._supply()

    @property
    def percent(self) -> float:
        """The true charge, 0-100."""
        return 100.0 * self.energy_wh / self.capacity_wh

    def motor_power_w(self) -> float:
        """What the motors draw: their mechanical power (back-EMF times current) and their copper losses."""
        return self.params.motor_power_w([(m.current_a, m.speed_radps) for m in self.motors])

    @property
    def charge_w(self) -> float:
        """The power into the cells on the dock: a full pack's energy over the charging time."""
        return self.capacity_wh * 3600.0 / self.charge_s

    def docked(self) -> bool:
        dock = self.dock()
        if dock is None or self.pose is None:
            return False
        here = self.pose()
        return math.hypot(here.x_m - dock.x_m, here.y_m - dock.y_m) <= DOCK_RADIUS_M

    def tick(self, now: float) -> None:
        dt = 0.0 if self._last is None else max(0.0, now - self._last)
        self._last = now
        self.charging = self.docked()
        # on the dock the charger carries the load and fills the cells in charge_s; off it the load drains them
        net_w = self.charge_w if self.charging else -(self.base_load_w + self.motor_power_w())
        self.energy_wh = min(self.capacity_wh, max(0.0, self.energy_wh + net_w * dt / 3600.0))
        ocv = self.params.voltage_at(self.percent)
        self.current_a = -net_w / max(ocv, 1.0)  # negative while charging: the terminal voltage rises above,
        full = self.params.voltage_at(100.0)      # up to the charger's constant-voltage limit
        self.terminal_v = min(ocv - self.internal_ohm * self.current_a, max(ocv, full))
        self._supply()

    def _supply(self) -> None:
        for motor in self.motors:
            motor.voltage_v = self.terminal_v


__all__ = ["DOCK_RADIUS_M", "SimBattery", "SuppliedMotor"]
