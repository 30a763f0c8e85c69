"""The motion inputs the 50 Hz control tick reads, written from other threads (dashboard) and the agent.

One small lock-protected object, so the web server's threads never touch the pipeline: they record a
timed command or a flag here and the next control tick picks it up. Times are on the robot's clock.

The operator's joystick is kept apart from the mux's ``joystick`` input: the dashboard writes the
former (`operate`), the agent's DriveJoystick leaf reads it and forwards it to the latter while the agent
is in a state that lets the operator drive. Were they one slot, the leaf would re-stamp its own output
every tick and a lost browser tab would never time out.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from atemr.msgs import CliffReadings, LaserScan, Twist
from atemr.skills.motion_pipeline import ControlInputs, Mode, TimedClearance, TimedTwist

Source = str  # "joystick" | "navigation" | "agent"


#: The safety stops the robot's wiring holds by name (`MotionInputs.set_safety_stop`), for whoever reports why
#: the robot is stopped.
CAN_BUS_STOP = "CAN bus fault"
HEARTBEAT_STOP = "heartbeat lost"


@dataclass
class MotionInputs:
    """Latest timed twists by source, the mode, awareness and the safety-stop reasons."""

    mode: Mode = "MANUAL"
    awareness: bool = False
    _twists: dict[Source, TimedTwist] = field(default_factory=dict)
    _operator: TimedTwist | None = None
    _stops: set[str] = field(default_factory=set)
    _depth: TimedClearance | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def offer(self, source: Source, twist: Twist, t: float) -> None:
        """Record ``twist`` from ``source`` at time ``t`` (it expires in the mux after its timeout)."""
        if source not in ("joystick", "navigation", "agent"):
            raise ValueError(f"unknown motion source {source!r}")
        with self._lock:
            self._twists[source] = TimedTwist(twist, t)

    def operate(self, twist: Twist, t: float) -> None:
        """The operator's joystick at time ``t`` (from the dashboard); the agent decides whether it drives."""
        with self._lock:
            self._operator = TimedTwist(twist, t)

    def operator(self) -> TimedTwist | None:
        """The operator's latest joystick command, or None before the first."""
        with self._lock:
            return self._operator

    def zero(self, t: float, sources: tuple[Source, ...] = ("joystick", "navigation", "agent")) -> None:
        """Command zero on ``sources`` at once (a stop that does not wait for the timeout)."""
        with self._lock:
            for source in sources:
                self._twists[source] = TimedTwist(Twist(), t)

    def latest(self, source: Source) -> TimedTwist | None:
        with self._lock:
            return self._twists.get(source)

    def set_safety_stop(self, reason: str, on: bool) -> None:
        """Hold (or release) a safety stop for ``reason``; the robot stops while any reason holds."""
        with self._lock:
            if on:
                self._stops.add(reason)
            else:
                self._stops.discard(reason)

    def set_depth_clearance(self, clearance: TimedClearance | None) -> None:
        """The depth obstacle layer's nearest obstacles round the robot (the slow and stop zones read them)."""
        with self._lock:
            self._depth = clearance

    @property
    def safety_stops(self) -> frozenset[str]:
        with self._lock:
            return frozenset(self._stops)

    def control_inputs(self, now: float, scan: LaserScan | None, cliff: CliffReadings | None) -> ControlInputs:
        """This tick's `ControlInputs`, read under the lock."""
        with self._lock:
            return ControlInputs(
                now=now, scan=scan, cliff=cliff,
                joystick=self._twists.get("joystick"), navigation=self._twists.get("navigation"),
                agent=self._twists.get("agent"), mode=self.mode, awareness=self.awareness,
                safety_stop=bool(self._stops), depth_clearance=self._depth,
            )
