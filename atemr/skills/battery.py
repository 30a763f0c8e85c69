"""The battery's state of charge from the motors' supply voltage (thesis recommendation 5.4 v: "include a
voltage sensor"; the RMD motors already measure it and report it in their status-1 reply, 0x9A).

`BatteryEstimator` is pure: it is handed each reading (time, supply voltage, the motors' currents) and
keeps a filtered open-circuit voltage, from which the pack's curve (`BatteryParams.curve`, open-circuit
volts per cell against percent; the default is a 7-cell Li-ion pack, 29.4 V full, table 3.3) gives the charge.

* **Bad readings are rejected, not used**: NaN or infinite, zero or negative, outside what the pack can
  show (below 2.5 V or above 4.35 V a cell), or a jump of more than ``max_jump_v`` from the filtered value
  (a bit error, a loose connector). A new level that persists (``confirm_readings`` readings agreeing with
  each other: a fresh pack swapped in) is taken as the truth again.
* **Voltage sag under load is compensated**: a pack's terminal voltage drops by its internal resistance
  times the current it delivers, so the estimator adds ``sag_ohm`` times that current back before the curve
  is read; otherwise every acceleration would read as a flatter battery. The current is what the motors
  draw, from their torque current and speed (`load_current_a`: back-EMF power and copper losses), plus
  the electronics' ``base_load_w``.
* **The reading is filtered**: an exponential filter with time constant ``filter_s`` on the compensated
  voltage, so the percent shown does not flicker with each reading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import pairwise

from atemr.domain.status import AtReturn, BatteryStatus

#: A 7-cell Li-ion pack (thesis table 3.3): open-circuit volts per cell → percent (a typical NMC curve).
LI_ION_CURVE: tuple[tuple[float, ...], ...] = (
    (3.00, 0.0), (3.30, 5.0), (3.45, 10.0), (3.55, 20.0), (3.62, 30.0), (3.68, 40.0), (3.74, 50.0),
    (3.80, 60.0), (3.88, 70.0), (3.96, 80.0), (4.06, 90.0), (4.20, 100.0),
)
#: What a cell can read at all; anything outside is a bad reading.
MIN_CELL_V = 2.5
MAX_CELL_V = 4.35


@dataclass(frozen=True)
class BatteryParams:
    """The pack, the estimator and the limits the robot reacts at (``battery:`` in the configuration)."""

    cells: int = field(default=7, metadata={"min": 1, "max": 30, "help": "cells in series (7: 29.4 V full)"})
    curve: tuple[tuple[float, ...], ...] = field(default=LI_ION_CURVE, metadata={
        "help": "open-circuit volts per cell against percent, [[V, %], ...] rising (default: Li-ion)"})
    sag_ohm: float = field(default=0.15, metadata={"min": 0.0, "max": 5.0,
                                                   "help": "the pack's internal resistance, ohm (sag compensation)"})
    base_load_w: float = field(default=15.0, metadata={"min": 0.0, "max": 1000.0,
                                                       "help": "power the electronics draw, W"})
    motor_ke_v_per_radps: float = field(default=0.6, metadata={"min": 0.0, "max": 10.0,
                                                               "help": "the motors' back-EMF constant, V/(rad/s)"})
    motor_winding_ohm: float = field(default=0.3, metadata={"min": 0.0, "max": 10.0,
                                                            "help": "the motors' winding resistance, ohm"})
    filter_s: float = field(default=5.0, metadata={"min": 0.0, "max": 600.0, "help": "filter time constant, s"})
    max_jump_v: float = field(default=1.5, metadata={"min": 0.1, "max": 50.0,
                                                     "help": "a reading further than this from the filtered one "
                                                             "is rejected"})
    confirm_readings: int = field(default=5, metadata={"min": 2, "max": 100,
                                                       "help": "readings agreeing on a new level to accept it"})
    warn_percent: float = field(default=20.0, metadata={"min": 0.0, "max": 100.0, "help": "warn below this"})
    return_percent: float = field(default=10.0, metadata={"min": 0.0, "max": 100.0,
                                                          "help": "end the task and go home below this"})
    critical_percent: float = field(default=5.0, metadata={"min": 0.0, "max": 100.0,
                                                           "help": "stop in place, critical, below this"})
    at_return: AtReturn = field(default="cancel", metadata={
        "help": "at the return limit: cancel the task, or let it finish; then go home"})

    def validate(self) -> None:
        if len(self.curve) < 2 or any(len(p) != 2 for p in self.curve):
            raise ValueError("'curve' needs at least two points [volts per cell, percent]")
        volts = [p[0] for p in self.curve]
        percents = [p[1] for p in self.curve]
        if any(b <= a for a, b in pairwise(volts)) or \
                any(b < a for a, b in pairwise(percents)):
            raise ValueError("'curve' must rise: volts strictly, percent never falling")
        if not all(MIN_CELL_V <= v <= MAX_CELL_V for v in volts) or not all(0 <= p <= 100 for p in percents):
            raise ValueError(f"'curve' volts per cell lie in [{MIN_CELL_V}, {MAX_CELL_V}], percent in [0, 100]")
        if not self.critical_percent <= self.return_percent <= self.warn_percent:
            raise ValueError("the limits must be ordered: critical_percent <= return_percent <= warn_percent")

    def status(self, reading: BatteryReading) -> BatteryStatus:
        """The estimate as the robot's consumers read it, with the limits it is compared with."""
        return BatteryStatus(reading.percent, reading.voltage_v, self.warn_percent, self.return_percent,
                             self.critical_percent, self.at_return)

    def motor_power_w(self, motors: list[tuple[float, float]]) -> float:
        """What motors running at ``(current A, speed rad/s)`` draw: back-EMF power and copper losses."""
        return sum(abs(i) * self.motor_ke_v_per_radps * abs(w) + i * i * self.motor_winding_ohm for i, w in motors)

    def load_current_a(self, voltage_v: float, motors: list[tuple[float, float]]) -> float:
        """The current the pack delivers at ``voltage_v`` to the electronics and to these motors."""
        return (self.base_load_w + self.motor_power_w(motors)) / max(voltage_v, 1.0)

    def percent_at(self, open_circuit_v: float) -> float:
        """The charge (0-100) of the pack at this open-circuit voltage, by the curve."""
        cell = open_circuit_v / self.cells
        if cell <= self.curve[0][0]:
            return float(self.curve[0][1])
        for (v0, p0), (v1, p1) in pairwise(self.curve):
            if cell <= v1:
                return float(p0 + (p1 - p0) * (cell - v0) / (v1 - v0))
        return float(self.curve[-1][1])

    def voltage_at(self, percent: float) -> float:
        """The open-circuit pack voltage at ``percent`` (the curve read backwards; the simulator's battery)."""
        p = min(100.0, max(0.0, percent))
        for (v0, p0), (v1, p1) in pairwise(self.curve):
            if p <= p1:
                return float(self.cells * (v0 + (v1 - v0) * ((p - p0) / (p1 - p0) if p1 > p0 else 0.0)))
        return float(self.cells * self.curve[-1][0])


@dataclass(frozen=True)
class BatteryReading:
    """The estimate after a reading: charge (percent), the filtered open-circuit voltage, the last raw voltage."""

    t: float
    percent: float
    open_circuit_v: float
    voltage_v: float


class BatteryEstimator:
    """See the module docstring; `update` with each reading, `latest` is the estimate (None before one)."""

    def __init__(self, params: BatteryParams | None = None) -> None:
        self.params = params or BatteryParams()
        self.latest: BatteryReading | None = None
        self.rejected = 0
        self.last_rejection: str | None = None
        self._filtered: float | None = None
        self._candidates: list[float] = []

    def update(self, t: float, voltage_v: float, motors: list[tuple[float, float]] | None = None) -> str | None:
        """Take one reading (``motors``: each motor's torque current and speed, for the sag); returns why it
        was rejected, None when it was used."""
        why = self._implausible(voltage_v)
        values = [v for m in motors or [] for v in m]
        if why is None and not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            why = f"motor current or speed {motors!r} is not a number"
        if why is not None:
            return self._reject(why)
        p = self.params
        ocv = voltage_v + p.sag_ohm * p.load_current_a(voltage_v, motors or [])
        if self._filtered is not None and abs(ocv - self._filtered) > p.max_jump_v:
            self._candidates.append(ocv)
            recent = self._candidates[-p.confirm_readings:]
            if len(recent) < p.confirm_readings or max(recent) - min(recent) > p.max_jump_v:
                return self._reject(f"{voltage_v:.2f} V jumps {ocv - self._filtered:+.2f} V from "
                                    f"{self._filtered:.2f} V")
            self._filtered = sum(recent) / len(recent)  # a new level, confirmed: a fresh pack
        elif self._filtered is None or self.latest is None:
            self._filtered = ocv
        else:
            dt = max(0.0, t - self.latest.t)
            alpha = 1.0 if p.filter_s <= 0 else 1.0 - math.exp(-dt / p.filter_s)
            self._filtered += alpha * (ocv - self._filtered)
        self._candidates.clear()
        self.latest = BatteryReading(t, p.percent_at(self._filtered), self._filtered, voltage_v)
        return None

    def _implausible(self, voltage_v: float) -> str | None:
        if isinstance(voltage_v, bool) or not isinstance(voltage_v, (int, float)) or not math.isfinite(voltage_v):
            return f"voltage {voltage_v!r} is not a number"
        if voltage_v <= 0:
            return f"voltage {voltage_v:g} V is not a battery's"
        lo, hi = self.params.cells * MIN_CELL_V, self.params.cells * MAX_CELL_V
        if not lo <= voltage_v <= hi:
            return f"{voltage_v:.2f} V is outside what a {self.params.cells}-cell pack can read ({lo:g}-{hi:g} V)"
        return None

    def _reject(self, why: str) -> str:
        self.rejected += 1
        self.last_rejection = why
        return why


__all__ = ["LI_ION_CURVE", "BatteryEstimator", "BatteryParams", "BatteryReading"]
