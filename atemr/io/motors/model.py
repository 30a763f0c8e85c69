"""A pure model of one MyActuator RMD-L-7015 hub motor: what the emulator answers and the simulator drives.

Physics, deliberately simple; speed and angle are exact in time (the same at any step size), current
and temperature are accurate to first order in the step:

* speed follows the commanded speed with first-order dynamics, time constant ``time_constant_s``
  (``coast_time_constant_s`` when the output is off); the step uses the exact exponential solution, and
  the shaft angle is its exact integral, so encoder counts do not depend on ``dt``;
* torque current is ``inertia_a_per_radps2 · acceleration + damping_a_per_radps · speed``, clamped;
* winding temperature rises with ``heating_c_per_a2s · I²`` and relaxes towards ambient with
  ``cooling_time_constant_s``;
* error flags (over-temperature, under-voltage) come from the temperature and supply voltage, from
  injected faults, and latch until cleared once their cause is gone — by V1.61's 0x9B (`clear_errors`), by
  a V4.2 motor itself for its level-2 errors (`clear_errors` with ``only``), or by V4.2's 0x76 system reset
  (`reset`); while any flag is set the motor's output is off, as the real driver protects itself;
* "unplugged" cuts the motor's power: no output, and the emulator stops answering;
* `comm_timeout` is the RMD's CAN communication-interruption protection tripping (the emulator trips it when
  no speed command has arrived for its ``comm_timeout_s``): the motor brakes to zero, forgets its command and
  reports ``comm_timed_out`` until the next speed command.

Deterministic: no randomness at all. Speeds are of the motor shaft in rad/s (the L-7015 is direct drive,
so this is the wheel's speed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from atemr.errors import HardwareError
from atemr.io.motors.rmd_codec import MotorErrorFlags

TWO_PI = 2.0 * math.pi
#: Counts per revolution of the L-series 14-bit single-turn encoder.
ENCODER_COUNTS = 1 << 14


@dataclass(frozen=True)
class RmdMotorParams:
    """Physical parameters of the model; defaults are plausible for an RMD-L-7015 on a 24 V base."""

    time_constant_s: float = 0.08
    coast_time_constant_s: float = 0.8
    max_speed_radps: float = 60.0
    max_current_a: float = 33.0
    inertia_a_per_radps2: float = 0.02
    damping_a_per_radps: float = 0.05
    ambient_c: float = 25.0
    heating_c_per_a2s: float = 0.01
    cooling_time_constant_s: float = 300.0
    over_temperature_c: float = 80.0
    supply_voltage_v: float = 24.0
    under_voltage_v: float = 18.0

    def __post_init__(self) -> None:
        for name in ("time_constant_s", "coast_time_constant_s", "max_speed_radps", "max_current_a",
                     "cooling_time_constant_s", "supply_voltage_v"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise HardwareError(f"motor parameter {name} must be a finite number > 0, got {value!r}",
                                    component="motor model")


class MotorMode(Enum):
    """What the motor's driver is doing: OFF (0x80, output disabled, command cleared), STOPPED (0x81, braking to
    zero, command kept for 0x88) or RUNNING (following the commanded speed)."""

    OFF = "off"
    STOPPED = "stopped"
    RUNNING = "running"


class RmdMotorModel:
    """One motor; call `step` with the elapsed time and read `speed_radps`, `encoder`, `temperature_c`, ...

    ``initial_angle_rad`` lets two motors start with different encoder readings.
    """

    def __init__(self, params: RmdMotorParams | None = None, *, initial_angle_rad: float = 0.0) -> None:
        self.params = params or RmdMotorParams()
        self.mode = MotorMode.RUNNING
        self.plugged = True
        self.voltage_v = self.params.supply_voltage_v
        self._command_radps = 0.0
        self._speed_radps = 0.0
        self._angle_rad = float(initial_angle_rad)
        self._current_a = 0.0
        self._temperature_c = self.params.ambient_c
        self._injected = MotorErrorFlags(0)
        self._latched = MotorErrorFlags(0)
        #: The communication-timeout protection has stopped the motor; a fresh speed command clears it.
        self.comm_timed_out = False

    # -- the simulator's protocol ---------------------------------------------------------------
    @property
    def speed_radps(self) -> float:
        """Actual shaft speed after the dynamics, rad/s."""
        return self._speed_radps

    def step(self, dt_s: float) -> None:
        """Advance by ``dt_s`` seconds: speed and angle exactly (target held constant), current and heat per step."""
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise HardwareError(f"step needs a finite dt >= 0, got {dt_s!r}", component="motor model")
        if dt_s == 0:
            return
        p = self.params
        enabled = self.output_enabled
        target = self._target(enabled)
        driven = enabled and self.mode is not MotorMode.OFF
        tau = p.time_constant_s if driven else p.coast_time_constant_s
        decay = math.exp(-dt_s / tau)
        v0 = self._speed_radps
        v1 = target + (v0 - target) * decay
        self._angle_rad += target * dt_s + (v0 - target) * tau * (1.0 - decay)
        self._speed_radps = v1
        accel = (v1 - v0) / dt_s
        current = (p.inertia_a_per_radps2 * accel + p.damping_a_per_radps * v1) if driven else 0.0
        self._current_a = max(-p.max_current_a, min(p.max_current_a, current))
        # temperature: exact solution of dT/dt = h·I² − (T − T_amb)/τ with I constant over the step
        t_eq = p.ambient_c + p.heating_c_per_a2s * self._current_a ** 2 * p.cooling_time_constant_s
        self._temperature_c = t_eq + (self._temperature_c - t_eq) * math.exp(-dt_s / p.cooling_time_constant_s)
        conditions = self._conditions()
        if conditions:
            self._latched |= conditions

    # -- commands (what the CAN commands do) ----------------------------------------------------
    def set_speed(self, speed_radps: float) -> None:
        """Speed closed-loop command (0xA2): follow ``speed_radps`` (clamped to the motor's limit)."""
        if not math.isfinite(speed_radps):
            raise HardwareError(f"speed command must be finite, got {speed_radps!r}", component="motor model")
        limit = self.params.max_speed_radps
        self._command_radps = max(-limit, min(limit, float(speed_radps)))
        self.mode = MotorMode.RUNNING
        self.comm_timed_out = False

    def stop(self) -> None:
        """Motor stop (0x81): brake to zero, keep the command for `run`."""
        if self.mode is MotorMode.RUNNING:
            self.mode = MotorMode.STOPPED

    def brake(self) -> None:
        """Same as `stop`: the driver holds zero speed actively."""
        self.stop()

    def run(self) -> None:
        """Motor running (0x88): resume the command held by `stop`."""
        if self.mode is MotorMode.STOPPED:
            self.mode = MotorMode.RUNNING

    def off(self) -> None:
        """Motor off (0x80): output disabled, command cleared; the shaft coasts."""
        self.mode = MotorMode.OFF
        self._command_radps = 0.0

    def comm_timeout(self) -> None:
        """The CAN communication-timeout protection trips: brake to zero and forget the command, so neither a
        late MOTOR_RUN nor anything else resumes a stale speed; only a fresh speed command (0xA2) drives again."""
        self.comm_timed_out = True
        self._command_radps = 0.0
        if self.mode is MotorMode.RUNNING:
            self.mode = MotorMode.STOPPED

    def clear_errors(self, only: MotorErrorFlags | None = None) -> MotorErrorFlags:
        """Clear error flags (V1.61 0x9B): latched flags whose cause is gone are cleared; returns what remains.

        ``only`` limits it to those flags: a V4.2 motor clears its level-2 errors by itself this way.
        """
        keep = self._latched & ~only if only is not None else MotorErrorFlags.NONE
        self._latched = keep | self._conditions()
        return self.error_flags

    def reset(self) -> None:
        """System reset (V4.2 0x76): the motor restarts as after power-up, command cleared, and latches only the
        errors whose cause is still there."""
        self._latched = self._conditions()
        self.plug()

    # -- faults ---------------------------------------------------------------------------------
    def inject_error(self, flags: MotorErrorFlags) -> None:
        """Make ``flags`` true conditions (a stuck sensor, a hot winding) until `clear_injected`."""
        self._injected |= flags
        self._latched |= flags

    def clear_injected(self) -> None:
        """Remove injected conditions (the flags stay latched until `clear_errors`)."""
        self._injected = MotorErrorFlags(0)

    def unplug(self) -> None:
        """Cut the motor off the bus and power: no output, no answers."""
        self.plugged = False

    def plug(self) -> None:
        """Reconnect; the motor comes back as after power-up with its command cleared."""
        self.plugged = True
        self.mode = MotorMode.RUNNING
        self._command_radps = 0.0
        self.comm_timed_out = False

    # -- readings -------------------------------------------------------------------------------
    @property
    def error_flags(self) -> MotorErrorFlags:
        """The error flags the motor reports (in its 0x9A status-1 reply)."""
        conditions = self._conditions()
        # Nearly always one of them is empty: no flag arithmetic then (it is slow, and this runs a few hundred
        # times a simulated second).
        if not conditions:
            return self._latched
        return conditions if not self._latched else self._latched | conditions

    @property
    def output_enabled(self) -> bool:
        """Whether the driver powers the winding: plugged in and no error flag."""
        return self.plugged and not self.error_flags

    @property
    def target_radps(self) -> float:
        """The speed the driver is steering towards now (zero when stopped, off or faulted)."""
        return self._target(self.output_enabled)

    def _target(self, enabled: bool) -> float:
        """`target_radps` given `output_enabled` (which `step` reads once)."""
        return self._command_radps if enabled and self.mode is MotorMode.RUNNING else 0.0

    @property
    def command_radps(self) -> float:
        """The last speed command, kept while stopped."""
        return self._command_radps

    @property
    def position_rad(self) -> float:
        """Multi-turn shaft angle since start, rad."""
        return self._angle_rad

    @property
    def encoder(self) -> int:
        """Single-turn 14-bit encoder reading, 0..16383."""
        return math.floor(self._angle_rad / TWO_PI * ENCODER_COUNTS) % ENCODER_COUNTS

    @property
    def current_a(self) -> float:
        """Torque current, A (signed like the speed)."""
        return self._current_a

    @property
    def temperature_c(self) -> float:
        """Winding temperature, °C."""
        return self._temperature_c

    def _conditions(self) -> MotorErrorFlags:
        flags = self._injected
        if self._temperature_c >= self.params.over_temperature_c:
            flags |= MotorErrorFlags.OVER_TEMPERATURE
        if self.voltage_v < self.params.under_voltage_v:
            flags |= MotorErrorFlags.UNDER_VOLTAGE
        return flags
