"""The speed ramp (thesis 3.4.1): smooth velocity, slow and stop zones, emergency, idle detection.

Per tick, in this order:

1. Zones. From the nearest obstacle *in the direction the base moves or is asked to move*: closer than
   ``stop_distance_m`` (0.28 m) → emergency: output zero at once, bypassing the ramp, until that
   clearance has stayed beyond the stop distance for ``resume_after_s`` (2 s). The stop zone is judged
   where the base would come to rest if it did not stop now: the next decision is one control period
   away, and zero commanded then still takes one driver period to reach the motors and their lag (first
   order: the base coasts speed × time constant) to stop the wheels. Together that is the base's speed
   times ``brake_latency_s`` (0.12 s: two 20 ms periods plus the RMD's 0.08 s time constant). So the
   emergency starts as soon as the clearance minus that distance falls below the stop distance, and the
   base stops at or beyond 0.28 m instead of inside its 0.25 m footprint; an emergency started early
   holds until the obstacle is farther than the stop distance plus the braking distance it started
   with, so the base does not creep on towards it every ``resume_after_s``. Closer than
   ``slow_distance_m`` (0.56 m) → the target is limited to ``slow_linear_mps`` (0.35 m/s) and
   ``slow_angular_radps`` (1.6 rad/s), and the slow zone is anticipated like the stop zone: towards an
   obstacle ahead (or behind, reversing) the linear target never exceeds the speed from which the base
   decelerates to ``slow_linear_mps`` by the zone's edge, so it enters the zone at slow speed rather than
   starting to brake there. `Clearance` gives three directions (from the hex pattern):
   front (ahead within ±60°), rear, side. Going forward the stop zone watches the front, reversing the
   rear, and the slow zone also the sides; turning on the spot never triggers the stop zone (KAY's
   footprint is round about its axle) but is slowed by anything near. Direction matters so that an
   operator can back away from the wall the base stopped at (after the resume delay), so that a person
   walking up behind a base that drives away does not brake it, and so that the base may pass beside
   an obstacle it is steering round.
2. Ramp. Linear and angular velocity each move towards the (limited) target by at most their
   acceleration limit times the elapsed time: linear in time (thesis 3.4.1; figure 3.23 is missing).
3. Idle. No state-changing command (a non-zero command, or one that differs from the previous one)
   for ``idle_after_s`` (8 s) → the base is idle; the reactive engine and the hardware read the flag.

Limits are one frozen `MotionLimits`, changed at run time only through `SpeedRamp.set_limits`, which
validates the whole new set (bounds, stop <= slow) and applies it atomically: a rejected value raises
`ConfigError` naming the key and keeps the old limits in force.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from atemr.clock import due
from atemr.msgs import ZERO_TWIST, Twist
from atemr.typed import Source, merge_into


@dataclass(frozen=True)
class MotionLimits:
    """Every limit of the safe-motion layer (docs/navigation.md#speed-ramp-and-safety-zones, thesis table
    3.2); SI units in the names."""

    max_linear_mps: float = field(
        default=1.6, metadata={"min": 0.0, "max": 1.8, "help": "top forward/reverse speed (spec up to 1.8)"}
    )
    max_angular_radps: float = field(default=2.0, metadata={"min": 0.0, "max": 6.0, "help": "top turn rate"})
    linear_accel_mps2: float = field(
        default=1.0, metadata={"min": 0.05, "max": 10.0, "help": "ramp slope of the linear speed, up and down"}
    )
    angular_accel_radps2: float = field(
        default=3.0, metadata={"min": 0.05, "max": 30.0, "help": "ramp slope of the turn rate, up and down"}
    )
    slow_distance_m: float = field(
        default=0.56, metadata={"min": 0.0, "max": 5.0, "help": "obstacle closer than this: slow zone"}
    )
    stop_distance_m: float = field(
        default=0.28, metadata={"min": 0.0, "max": 5.0, "help": "obstacle closer than this: emergency stop"}
    )
    slow_linear_mps: float = field(default=0.35, metadata={"min": 0.0, "max": 1.8, "help": "speed in the slow zone"})
    slow_angular_radps: float = field(
        default=1.6, metadata={"min": 0.0, "max": 6.0, "help": "turn rate in the slow zone"}
    )
    resume_after_s: float = field(
        default=2.0, metadata={"min": 0.0, "max": 60.0, "help": "clear time before leaving an emergency"}
    )
    idle_after_s: float = field(
        default=8.0, metadata={"min": 0.1, "max": 3600.0, "help": "no state-changing command this long: idle"}
    )
    brake_latency_s: float = field(
        default=0.12,
        metadata={"min": 0.0, "max": 1.0,
                  "help": "speed x this = travel before the base can stop (next control tick + driver period + "
                          "motor time constant): the stop zone triggers that much early"},
    )

    def validate(self) -> None:
        """Cross-field checks, called by `atemr.typed.merge_into` (ValueError → ConfigError)."""
        if self.stop_distance_m > self.slow_distance_m:
            raise ValueError(
                f"stop_distance_m ({self.stop_distance_m}) must not exceed slow_distance_m ({self.slow_distance_m})"
            )


def checked_limits(changes: Mapping[str, Any] | MotionLimits, base: MotionLimits | None = None) -> MotionLimits:
    """``base`` with ``changes`` applied and every bound checked; raises `ConfigError` naming the key.

    ``changes`` is a mapping of field names (strings are parsed, as from a settings form) or a whole
    `MotionLimits` (checked as if every field were given, since a dataclass can be built with any values).
    """
    base = base or MotionLimits()
    if isinstance(changes, MotionLimits):
        changes = dataclasses.asdict(changes)
    return merge_into(base, changes, Source("argument"))


@dataclass(frozen=True)
class Clearance:
    """Nearest obstacle ahead, behind and beside the base, metres from the base origin (inf: none).

    From `atemr.skills.hexpattern.HexSectors.nearest_by_direction`: ahead is within ±60° of the heading,
    the path a round footprint sweeps.
    """

    front_m: float = math.inf
    rear_m: float = math.inf
    side_m: float = math.inf


@dataclass(frozen=True)
class RampOutput:
    """One tick of the ramp: the twist to drive and the state behind it, for telemetry."""

    twist: Twist
    emergency: bool
    slow: bool
    idle: bool
    #: The clearance the zones were judged on this tick (direction-dependent, see module doc).
    guard_m: float


def _signs(*values: float) -> set[int]:
    return {1 if v > 0 else -1 for v in values if v != 0.0}


def _towards(value: float, target: float, max_step: float) -> float:
    return target if abs(target - value) <= max_step else value + math.copysign(max_step, target - value)


class IdleDetector:
    """Idle after ``idle_after_s`` without a state-changing command (thesis 3.4.1).

    A command changes the state when it asks the base to move or differs from the previous one; a
    joystick at rest streaming zeros does not. Time starts at the first observation.
    """

    def __init__(self) -> None:
        self._last_change: float | None = None
        self._last_command: Twist | None = None

    def observe(self, now: float, command: Twist | None, idle_after_s: float) -> bool:
        """Record ``command`` (None: no operator/planner command this tick) and return the idle flag."""
        if self._last_change is None:
            self._last_change = now
        if command is not None:
            if not command.is_zero or command != self._last_command:
                self._last_change = now
            self._last_command = command
        return due(now, self._last_change + idle_after_s)

    def wake(self, now: float) -> None:
        """Count ``now`` as a state change (mode switch, new goal): the base is busy again."""
        self._last_change = now


class SpeedRamp:
    """The stateful ramp: current velocity, emergency latch, idle detector, limits in force."""

    def __init__(self, limits: MotionLimits | Mapping[str, Any] | None = None) -> None:
        self._limits = checked_limits(limits or {})
        self._v = 0.0
        self._w = 0.0
        self._last_now: float | None = None
        self._emergency = False
        self._clear_since: float | None = None
        #: The braking distance the emergency was started with: while it lasts, the stop zone is that much deeper.
        self._hold_m = 0.0
        self._idle = False
        self.idle_detector = IdleDetector()

    @property
    def limits(self) -> MotionLimits:
        return self._limits

    @property
    def velocity(self) -> Twist:
        """The ramp's current output velocity."""
        return Twist(self._v, self._w)

    @property
    def emergency(self) -> bool:
        return self._emergency

    @property
    def idle(self) -> bool:
        """The idle flag as of the last `step`."""
        return self._idle

    def set_limits(self, changes: Mapping[str, Any] | MotionLimits) -> MotionLimits:
        """Validate and apply new limits atomically; on `ConfigError` the old limits stay in force."""
        self._limits = checked_limits(changes, self._limits)
        return self._limits

    def braking_distance_m(self, direction: int = 1) -> float:
        """How far the base still travels in ``direction`` (+1 forward, -1 reverse) after a zero command now:
        its current speed that way times ``brake_latency_s`` (0 when it moves the other way or stands)."""
        return max(direction * self._v, 0.0) * self._limits.brake_latency_s

    def _slow_envelope(self, clearance_m: float) -> float:
        """The fastest the base may go towards an obstacle ``clearance_m`` away and still be down to the slow
        speed when it reaches the slow zone: decelerating at ``linear_accel_mps2`` from where a command sent
        now takes effect (the base covers speed x ``brake_latency_s`` first, as for the stop zone)."""
        lim = self._limits
        ahead = clearance_m - lim.slow_distance_m - abs(self._v) * lim.brake_latency_s
        return math.sqrt(lim.slow_linear_mps ** 2 + 2.0 * lim.linear_accel_mps2 * max(ahead, 0.0))

    def halt(self) -> None:
        """Drop the current velocity to zero at once (a veto downstream: cliff stop, watchdog)."""
        self._v = self._w = 0.0

    def step(
        self,
        now: float,
        target: Twist,
        clearance: Clearance | None,
        *,
        command: Twist | None = None,
    ) -> RampOutput:
        """Advance to ``now`` towards ``target``.

        ``clearance`` None means no trustworthy scan: the base may move, but only at slow-zone limits.
        ``command`` is the operator's or planner's command this tick, for the idle detector (the
        reactive engine's own motion is not a command and must not wake the base).
        """
        lim = self._limits
        dt = 0.0 if self._last_now is None else max(0.0, now - self._last_now)
        self._last_now = now if self._last_now is None else max(now, self._last_now)
        tv, tw = target.linear_mps, target.angular_radps
        if not (math.isfinite(tv) and math.isfinite(tw)):
            tv = tw = 0.0
        idle = self._idle = self.idle_detector.observe(now, command, lim.idle_after_s)

        directions = _signs(self._v, tv)
        if clearance is None:
            guard = lim.slow_distance_m  # blind: slow, never an emergency on no data
            stop_guard = at_rest = math.inf
        else:
            by_dir = {1: clearance.front_m, -1: clearance.rear_m}
            stop_guard = min((by_dir[d] for d in directions), default=math.inf)
            # the clearance left once the base has come to rest from its current speed
            at_rest = min((by_dir[d] - self.braking_distance_m(d) for d in directions), default=math.inf)
            around = min(clearance.front_m, clearance.rear_m)
            guard = min(stop_guard, clearance.side_m) if directions else min(around, clearance.side_m)

        if at_rest < lim.stop_distance_m:
            braking = max(self.braking_distance_m(d) for d in directions)
            self._hold_m = max(self._hold_m, braking) if self._emergency else braking
            self._emergency = True
            self._clear_since = None
        elif self._emergency and stop_guard < lim.stop_distance_m + self._hold_m:
            # started early by the braking distance, the base may rest just outside the stop zone: the obstacle
            # has not left until it is that much farther, so the base does not creep towards it every 2 s
            self._clear_since = None
        elif self._emergency:
            if self._clear_since is None:
                self._clear_since = now
            if due(now, self._clear_since + lim.resume_after_s):
                self._emergency = False
                self._clear_since = None
                self._hold_m = 0.0
        if self._emergency:
            self.halt()
            return RampOutput(ZERO_TWIST, True, False, idle, stop_guard)

        slow = guard < lim.slow_distance_m or clearance is None
        max_v = min(lim.max_linear_mps, lim.slow_linear_mps) if slow else lim.max_linear_mps
        max_w = min(lim.max_angular_radps, lim.slow_angular_radps) if slow else lim.max_angular_radps
        tv = min(max(tv, -max_v), max_v)
        tw = min(max(tw, -max_w), max_w)
        if clearance is not None and tv != 0.0:
            tv = math.copysign(min(abs(tv), self._slow_envelope(by_dir[1 if tv > 0 else -1])), tv)
        self._v = _towards(self._v, tv, lim.linear_accel_mps2 * dt)
        self._w = _towards(self._w, tw, lim.angular_accel_radps2 * dt)
        return RampOutput(Twist(self._v, self._w), False, slow, idle, guard)


__all__ = ["Clearance", "IdleDetector", "MotionLimits", "RampOutput", "SpeedRamp", "checked_limits"]
