"""The whole 50 Hz safe-motion tick as one pure object: sensors and commands in, wheel speeds out.

    scan ─► hex (HEX-90: engines, and the ramp's zones) ─► reactive engine (awareness on)
    joystick / agent / navigation / reactive / safety stop ─► twist mux ─► speed ramp ─► cliff stop
    ─► differential drive ─► wheel speed command

No I/O and no clock: ``now`` and everything else arrives in `ControlInputs`; the result
(`ControlResult`) carries the wheel command and every decision behind it for telemetry. The object
keeps only the state that must live between ticks (mux inputs, ramp velocity and latches, caches).

Decisions beyond the single skills (docs/navigation.md#the-motion-pipeline, docs/testing.md#what-the-robot-promises):

* Admissible mux inputs: MANUAL mode → joystick and agent; AUTO → agent and navigation; the reactive
  input only with the awareness flag. The agent's own motions (Rotate, recoveries) are above navigation
  and below the operator's joystick.
* The reactive engine publishes only when it has a job: the base is idle (IDLE engine, full control),
  or in MANUAL mode the operator drives (MANUAL engine blended with the joystick). Otherwise it is
  absent and the joystick or navigation gets through. Its own motion is not a command, so it does not
  wake an idle base.
* Hard stops bypass the ramp: the safety stop, the watchdog (no fresh input: a lost browser tab stops
  the base the moment its last command turns 0.5 s old), the stop zone and the cliff stop.
* A scan is up to one lidar period old (0.1 s at 10 Hz): at 0.35 m/s the base has moved 3.5 cm since,
  more than the 3 cm between KAY's footprint and the stop distance. So the front and rear clearances
  are reduced by the distance the base has driven (by its own commands) since the scan was taken.
* And the base does not stop the tick zero is commanded: the ramp judges the stop zone where the base
  would come to rest (clearance minus speed × ``MotionLimits.brake_latency_s``: the next control tick,
  the driver's period and the motors' lag), so it stops at or beyond the stop distance.
* A scan older than ``scan_max_age_s`` is no scan: the ramp drives blind at slow-zone limits and the
  reactive engine is silent.
* What the depth camera's obstacle layer holds near the robot (`ControlInputs.depth_clearance`: a table top
  in front of the mast, a shoe under the lidar's plane) joins the lidar's clearances, nearest wins, aged by
  the distance driven since it was computed like the scan's: the slow and stop zones treat a table top like a
  wall. One older than ``scan_max_age_s`` is ignored (the depth device's health says why).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from atemr.errors import ConfigError
from atemr.msgs import CliffReadings, LaserScan, Twist, WheelSpeeds
from atemr.skills.cliff import CliffStop
from atemr.skills.diff_drive import DiffDrive
from atemr.skills.hexpattern import DEFAULT_RADIUS_M, HEX90, HexSectors, hex_pattern, load_compiled
from atemr.skills.ramp import Clearance, MotionLimits, SpeedRamp
from atemr.skills.reactive import ReactiveEngine
from atemr.skills.twist_mux import (
    DEFAULT_TIMEOUT_S,
    JOYSTICK,
    NAVIGATION,
    REACTIVE,
    SAFETY_STOP,
    MuxInput,
    TwistMux,
)

Mode = Literal["MANUAL", "AUTO"]
#: The agent's own velocity input (`atemr.trees.ports.VelocitySource` "agent").
AGENT = "agent"

#: Mux inputs per mode; REACTIVE is added when the awareness flag is on.
MODE_INPUTS: dict[str, frozenset[str]] = {
    "MANUAL": frozenset({JOYSTICK, AGENT}),
    "AUTO": frozenset({AGENT, NAVIGATION}),
}


@dataclass(frozen=True)
class TimedTwist:
    """A velocity command and the time it was given (seconds on the robot's clock)."""

    twist: Twist
    t: float


@dataclass(frozen=True)
class TimedClearance:
    """Nearest obstacles by direction from another source than the lidar (the depth layer), as of ``t``."""

    clearance: Clearance
    t: float


@dataclass(frozen=True)
class ControlInputs:
    """Everything one control tick reads."""

    now: float
    scan: LaserScan | None = None
    cliff: CliffReadings | None = None
    joystick: TimedTwist | None = None
    navigation: TimedTwist | None = None
    agent: TimedTwist | None = None
    mode: Mode = "MANUAL"
    awareness: bool = False
    safety_stop: bool = False
    #: The depth obstacle layer's clearances (`atemr.skills.nav.voxel_layer.VoxelLayer.clearance`), if any.
    depth_clearance: TimedClearance | None = None
    #: New limits to apply before this tick (validated; rejected → `ConfigError`, old limits kept).
    limits: MotionLimits | Mapping[str, Any] | None = None


@dataclass(frozen=True)
class ControlResult:
    """One tick's output and the reasons behind it."""

    now: float
    wheels: WheelSpeeds
    twist: Twist
    #: Which mux input or lock won (None: nothing fresh, the watchdog zero).
    source: str | None
    mux_twist: Twist
    reactive: Twist | None
    emergency: bool
    slow: bool
    idle: bool
    watchdog: bool
    safety_stop: bool
    cliff_stop: bool
    cliff_drops: tuple[bool, bool, bool]
    #: The cliff readings were missing or stale (the secondary core silent): the drops are assumed, not seen.
    cliff_blind: bool
    blind: bool
    clearance: Clearance | None
    sectors: HexSectors | None
    tau: float = 0.0

    def telemetry(self) -> dict[str, Any]:
        """A JSON-ready summary for the dashboard and logs."""

        def num(x: float) -> float | None:
            return round(x, 4) if math.isfinite(x) else None

        return {
            "t": self.now,
            "wheels_radps": [num(self.wheels.left_radps), num(self.wheels.right_radps)],
            "twist": [num(self.twist.linear_mps), num(self.twist.angular_radps)],
            "source": self.source,
            "emergency": self.emergency,
            "slow": self.slow,
            "idle": self.idle,
            "watchdog": self.watchdog,
            "safety_stop": self.safety_stop,
            "cliff_stop": self.cliff_stop,
            "cliff_drops": list(self.cliff_drops),
            "cliff_blind": self.cliff_blind,
            "blind": self.blind,
            "hex_m": None if self.sectors is None else {k: num(v) for k, v in self.sectors.as_dict().items()},
            "clearance_m": None
            if self.clearance is None
            else {k: num(getattr(self.clearance, f"{k}_m")) for k in ("front", "rear", "side")},
        }


@dataclass(frozen=True)
class PipelineSettings:
    """Fixed settings of the pipeline (run-time-changeable limits live in `MotionLimits`)."""

    mux_timeout_s: float = DEFAULT_TIMEOUT_S
    scan_max_age_s: float = 0.5
    radius_m: float = DEFAULT_RADIUS_M
    drive: DiffDrive = field(default_factory=DiffDrive)

    def __post_init__(self) -> None:
        for name in ("mux_timeout_s", "scan_max_age_s", "radius_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"motion pipeline: {name} must be a positive number, got {value!r}")


class MotionPipeline:
    """The safe-motion layer of the base; call `tick` at 50 Hz.

    ``reactive`` defaults to the shipped IDLE and MANUAL engines; ``cliff`` to the simulator's sensor
    geometry with missing readings treated as drops.
    """

    def __init__(
        self,
        limits: MotionLimits | Mapping[str, Any] | None = None,
        *,
        settings: PipelineSettings | None = None,
        reactive: ReactiveEngine | None = None,
        cliff: CliffStop | None = None,
    ) -> None:
        self.settings = settings or PipelineSettings()
        s = self.settings
        self.ramp = SpeedRamp(limits)
        self.mux = TwistMux(
            [
                MuxInput(REACTIVE, 30, s.mux_timeout_s),
                MuxInput(JOYSTICK, 20, s.mux_timeout_s),
                MuxInput(AGENT, 15, s.mux_timeout_s),
                MuxInput(NAVIGATION, 10, s.mux_timeout_s),
            ],
            locks={SAFETY_STOP: 100},
        )
        self.reactive = reactive or ReactiveEngine()
        self.cliff = cliff or CliffStop()
        self.drive = s.drive
        self._scan: LaserScan | None = None
        load_compiled()  # the hex pattern's loop, ready before the first scan
        self._hex: HexSectors | None = None
        #: The scan's nearest obstacle by direction, found once per scan (a control tick runs five times a scan).
        self._scan_clearance = Clearance()
        self._mode: str | None = None
        self._awareness: bool | None = None
        # dead reckoning along the heading from our own commands, to age the scan's clearances
        self._travel_m = 0.0
        self._travel_at_scan_m = 0.0
        self._depth: TimedClearance | None = None
        self._travel_at_depth_m = 0.0
        self._last_now: float | None = None
        self._last_v = 0.0

    @property
    def limits(self) -> MotionLimits:
        return self.ramp.limits

    def set_limits(self, changes: MotionLimits | Mapping[str, Any]) -> MotionLimits:
        """Validate and apply new limits (settings page); a rejected value keeps the old limits."""
        return self.ramp.set_limits(changes)

    def _hex_pattern(self, scan: LaserScan) -> HexSectors:
        """The HEX-90 sectors of one scan (a separate method so a benchmark can swap the algorithm)."""
        return hex_pattern(scan, HEX90, self.settings.radius_m)

    def _sectors(self, scan: LaserScan | None, now: float) -> HexSectors | None:
        """HEX-90 sectors of the latest scan, recomputed only when a new scan arrives; None if stale."""
        if scan is None or not (now - scan.t <= self.settings.scan_max_age_s):
            return None
        if scan is not self._scan or self._hex is None:
            self._hex = self._hex_pattern(scan)
            self._scan_clearance = Clearance(*self._hex.nearest_by_direction())
            self._scan = scan
            self._travel_at_scan_m = self._travel_m - self._last_v * max(0.0, now - scan.t)
        return self._hex

    def _aged(self, clearance: Clearance, travel_then_m: float) -> Clearance:
        """``clearance`` as of now: reduced by the distance driven (by our own commands) since it was measured."""
        moved = self._travel_m - travel_then_m
        return Clearance(clearance.front_m - max(moved, 0.0), clearance.rear_m - max(-moved, 0.0), clearance.side_m)

    def _with_depth(self, clearance: Clearance, depth: TimedClearance | None, now: float) -> Clearance:
        """The lidar's clearances with the depth layer's, nearest wins (a stale depth clearance is ignored)."""
        if depth is None or not (now - depth.t <= self.settings.scan_max_age_s):
            return clearance
        if depth is not self._depth:
            self._depth = depth
            self._travel_at_depth_m = self._travel_m - self._last_v * max(0.0, now - depth.t)
        seen = self._aged(depth.clearance, self._travel_at_depth_m)
        return Clearance(min(clearance.front_m, seen.front_m), min(clearance.rear_m, seen.rear_m),
                         min(clearance.side_m, seen.side_m))

    def _take_inputs(self, inputs: ControlInputs) -> None:
        """Check the time and mode, count the distance driven since the last tick, apply new limits, note a mode
        or awareness switch (a state change for the idle detector), and hand the commands to the mux."""
        now = inputs.now
        if not math.isfinite(now):
            raise ConfigError(f"motion pipeline: now must be a finite time, got {now!r}")
        if self._last_now is not None and now > self._last_now:
            self._travel_m += self._last_v * (now - self._last_now)
        self._last_now = now
        if inputs.mode not in MODE_INPUTS:
            raise ConfigError(f"motion pipeline: mode must be MANUAL or AUTO, got {inputs.mode!r}")
        if inputs.limits is not None and inputs.limits != self.limits:
            self.set_limits(inputs.limits)
        if (inputs.mode, inputs.awareness) != (self._mode, self._awareness):
            if self._mode is not None:
                self.ramp.idle_detector.wake(now)  # a mode or awareness switch is a state change
            self._mode, self._awareness = inputs.mode, inputs.awareness
        for name, cmd in ((JOYSTICK, inputs.joystick), (NAVIGATION, inputs.navigation), (AGENT, inputs.agent)):
            if cmd is not None:
                self.mux.publish(name, cmd.twist, cmd.t)
        self.mux.set_lock(SAFETY_STOP, inputs.safety_stop)

    def _reactive_twist(self, mode: str, hexes: HexSectors, now: float) -> tuple[Twist | None, float]:
        """The reactive layer's twist and τ: assisting a moving joystick in MANUAL, the IDLE engine while idle,
        else none."""
        joystick = self.mux.fresh_command(JOYSTICK, now)
        if mode == "MANUAL" and joystick is not None and not joystick.is_zero:
            assist = self.reactive.manual_assist(hexes, joystick)
            return assist.twist, assist.tau
        if self.ramp.idle:
            return self.reactive.idle_twist(hexes), 0.0
        return None, 0.0

    def tick(self, inputs: ControlInputs) -> ControlResult:
        """One control period at ``inputs.now``."""
        now = inputs.now
        self._take_inputs(inputs)
        admissible = set(MODE_INPUTS[inputs.mode])

        # the operator's or planner's command this tick (for idle detection and the MANUAL engine)
        command: Twist | None = None
        for name in (JOYSTICK, AGENT) if inputs.mode == "MANUAL" else (AGENT, NAVIGATION):
            command = self.mux.fresh_command(name, now)
            if command is not None:
                break

        hexes = self._sectors(inputs.scan, now)
        reactive: Twist | None = None
        tau = 0.0
        if inputs.awareness and hexes is not None:
            admissible.add(REACTIVE)
            reactive, tau = self._reactive_twist(inputs.mode, hexes, now)
        if reactive is not None:
            self.mux.publish(REACTIVE, reactive, now)
        else:
            self.mux.clear(REACTIVE)

        chosen = self.mux.select(now, admissible)
        watchdog = not chosen.fresh
        if watchdog or chosen.locked:
            self.ramp.halt()  # lost input or safety stop: stop now, not along the ramp
        clearance = None
        if hexes is not None:
            clearance = self._aged(self._scan_clearance, self._travel_at_scan_m)
            clearance = self._with_depth(clearance, inputs.depth_clearance, now)
        ramped = self.ramp.step(now, chosen.twist, clearance, command=command)
        verdict = self.cliff.check(now, ramped.twist, inputs.cliff)
        if verdict.stopped:
            self.ramp.halt()
        final = verdict.twist
        self._last_v = final.linear_mps
        return ControlResult(
            now=now,
            wheels=self.drive.command(final),
            twist=final,
            source=chosen.source,
            mux_twist=chosen.twist,
            reactive=reactive,
            emergency=ramped.emergency,
            slow=ramped.slow,
            idle=ramped.idle,
            watchdog=watchdog,
            safety_stop=chosen.locked,
            cliff_stop=verdict.stopped,
            cliff_drops=verdict.drops,
            cliff_blind=verdict.blind,
            blind=hexes is None,
            clearance=clearance,
            sectors=hexes,
            tau=tau,
        )


class MotionControl:
    """A scheduler component around a `MotionPipeline` (rate: 50 Hz), for wiring.

    ``read(now)`` gathers this tick's `ControlInputs` (latest scan, cliff readings, commands, mode,
    flags) from wherever the robot keeps them; ``command(wheels)`` hands the wheel speeds to the motor
    driver. ``last`` is the latest `ControlResult` for telemetry. If the tick raises, zero is commanded
    before the error reaches the scheduler, and `shutdown` commands zero too.
    """

    def __init__(
        self,
        pipeline: MotionPipeline,
        read: Callable[[float], ControlInputs],
        command: Callable[[WheelSpeeds], None],
        *,
        name: str = "motion",
    ) -> None:
        self.name = name
        self.pipeline = pipeline
        self.read = read
        self.command = command
        self.last: ControlResult | None = None

    def tick(self, now: float) -> None:
        try:
            result = self.pipeline.tick(self.read(now))
        except Exception:
            self.command(WheelSpeeds())
            raise
        self.last = result
        self.command(result.wheels)

    def shutdown(self) -> None:
        self.command(WheelSpeeds())


__all__ = [
    "AGENT",
    "MODE_INPUTS",
    "ControlInputs",
    "ControlResult",
    "Mode",
    "MotionControl",
    "MotionPipeline",
    "PipelineSettings",
    "TimedClearance",
    "TimedTwist",
]
