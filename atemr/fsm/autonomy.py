"""Operator autonomy levels (as in FlexBE): which transitions the agent may take on its own.

A transition of the agent document may carry ``autonomy: off | low | high | full``; the robot has an
operator-set level (the dashboard's control, ``agent.autonomy`` in the configuration). A transition whose
level is *above* the robot's is not taken automatically: when its own guards hold, the `AutonomyGate`
opens a `ConfirmRequest` and the trigger is refused for now ("waits for the operator"). The agent then
holds the robot still (no tree ticks, zero motion) until the operator confirms or denies in the browser,
or until ``timeout_s`` of robot time pass.

- confirm: the same trigger is fired again with the same arguments; the guards decide again (a goal that
  became invalid meanwhile takes the invalid-goal path) and the gate lets this one transition through;
- deny or timeout (the safe default): the transition is not taken, the machine stays in its source state,
  and the transition's ``on_deny`` trigger (if it names one, e.g. ``cancel``) is fired;
- a state change before the answer (a fault, a power-off, a cancel) supersedes the request;
- raising the robot's level to the transition's own confirms it (recorded as decided by ``level <L>``).

Safety transitions are never gated: those into ERROR or SHUTDOWN (critical failure, errors, faults,
shutdown, restart, power-off) and the triggers in `SAFETY_TRIGGERS` (cancel, emergency, ...). The
document validator refuses an ``autonomy`` on them, and the gate ignores one given programmatically.

The default robot level is ``full``: nothing is gated and the shipped behaviour is unchanged until the
operator lowers it. Every request and its outcome (by whom, when) is a `TransitionRecord` in the trace.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any, Literal, cast

from atemr.domain.status import top_level
from atemr.errors import ConfigError

Level = Literal["off", "low", "high", "full"]
#: The levels, lowest first.
LEVELS: tuple[Level, ...] = ("off", "low", "high", "full")
#: The robot's level when nobody set one: nothing is gated.
DEFAULT_LEVEL: Level = "full"
#: Robot seconds a request waits for the operator before the safe default (deny) applies.
DEFAULT_TIMEOUT_S = 30.0
#: Triggers that are always safety transitions, whatever their destination.
SAFETY_TRIGGERS = frozenset({"cancel", "emergency", "emergency_stop", "power_off", "shutdown", "fault",
                             "critical_failure", "escalate"})
#: Top-level destinations that make a transition a safety transition.
SAFETY_STATES = frozenset({"ERROR", "SHUTDOWN"})

Decision = Literal["requested", "confirmed", "denied", "timed_out", "superseded"]


def rank(level: str) -> int:
    """The level's position in `LEVELS` (raises `ConfigError` for an unknown one)."""
    try:
        return LEVELS.index(cast(Level, level))
    except ValueError:
        raise ConfigError(f"unknown autonomy level {level!r}; levels: {', '.join(LEVELS)}") from None


def safety_reason(trigger: str, dest: str) -> str | None:
    """Why a transition is a safety transition (never gated), or None when it is not one."""
    if trigger in SAFETY_TRIGGERS:
        return f"'{trigger}' is a safety trigger"
    if top_level(dest) in SAFETY_STATES:
        return f"it leads to {top_level(dest)}"
    return None


@dataclass(frozen=True)
class ConfirmRequest:
    """One transition waiting for the operator."""

    id: int
    t: float
    deadline: float
    trigger: str
    source: str
    dest: str
    level: Level
    robot_level: Level
    index: int
    origin: str = ""
    reason: str = ""
    on_deny: str | None = None
    kwargs: dict[str, Any] = field(default_factory=dict, compare=False)

    def as_dict(self) -> dict[str, Any]:
        """JSON for the dashboard (the event's arguments are summarised, not sent)."""
        return {"id": self.id, "t": self.t, "deadline": self.deadline, "trigger": self.trigger,
                "source": self.source, "dest": self.dest, "level": self.level, "robot_level": self.robot_level,
                "origin": self.origin, "reason": self.reason, "on_deny": self.on_deny,
                "arguments": sorted(self.kwargs)}


@dataclass(frozen=True)
class Answer:
    """The operator's answer to request ``request_id`` (queued from a web thread)."""

    request_id: int
    confirm: bool
    by: str


class AutonomyGate:
    """The robot's level, the pending request and the operator's answers. Thread-safe.

    The agent's thread opens requests (`open`), lets a confirmed one through (`approved`) and resolves
    answers and timeouts (`take_answer`, `expired`); web threads `set_level` and `answer`.
    """

    def __init__(self, level: str = DEFAULT_LEVEL, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        rank(level)
        if not timeout_s > 0:
            raise ConfigError(f"the confirmation timeout must be positive, got {timeout_s!r}")
        self._level = cast(Level, level)
        self.timeout_s = float(timeout_s)
        self._lock = threading.Lock()
        self._answers: list[Answer] = []
        self._next_id = 1
        self.pending: ConfirmRequest | None = None
        #: The request confirmed and being fired now (only its transition passes the gate).
        self.confirmed: tuple[ConfirmRequest, str] | None = None

    @property
    def level(self) -> Level:
        with self._lock:
            return self._level

    def set_level(self, level: str) -> Level:
        """Set the robot's level (raises `ConfigError` for an unknown one); returns it."""
        rank(level)
        with self._lock:
            self._level = cast(Level, level)
            return self._level

    def gates(self, level: str | None) -> bool:
        """Whether a transition of ``level`` needs the operator at the robot's current level."""
        return level is not None and rank(level) > rank(self.level)

    def open(self, *, now: float, trigger: str, source: str, dest: str, level: Level, index: int, origin: str,
             reason: str, on_deny: str | None, kwargs: dict[str, Any]) -> ConfirmRequest:
        with self._lock:
            request = ConfirmRequest(self._next_id, now, now + self.timeout_s, trigger, source, dest, level,
                                     self._level, index, origin, reason, on_deny, dict(kwargs))
            self._next_id += 1
            self.pending = request
            self._answers.clear()
            return request

    def answer(self, request_id: int, confirm: bool, by: str) -> str | None:
        """Queue the operator's answer; returns why it cannot be taken (None: queued for the next tick)."""
        with self._lock:
            pending = self.pending
            if pending is None:
                return "no transition is waiting for confirmation"
            if request_id != pending.id:
                return f"request {request_id} is no longer pending (now {pending.id}: {pending.trigger})"
            self._answers.append(Answer(request_id, confirm, by))
            return None

    def take_answer(self) -> Answer | None:
        """The first answer to the pending request, if any (consumed)."""
        with self._lock:
            pending = self.pending
            answers = [a for a in self._answers if pending is not None and a.request_id == pending.id]
            self._answers.clear()
            return answers[0] if answers else None

    def close(self) -> ConfirmRequest | None:
        """Forget the pending request (answered, timed out or superseded); returns it."""
        with self._lock:
            request, self.pending = self.pending, None
            return request

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            return {"level": self._level, "levels": list(LEVELS), "timeout_s": self.timeout_s,
                    "pending": self.pending.as_dict() if self.pending is not None else None}
