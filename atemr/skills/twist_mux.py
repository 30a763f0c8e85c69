"""The twist multiplexer: one velocity command out of several sources, by priority and freshness.

Like ROS's twist_mux: every input has a priority and a timeout; the freshest-enough input with the
highest priority wins; an input whose last command is older than its timeout counts as absent, so a lost
browser tab or a crashed planner stops the robot instead of leaving its last command running. Locks
(the safety stop) have a priority too and, while engaged, silence every input below it with zero.

ATEMR's order (docs/navigation.md#twist-mux), highest first: safety stop > reactive engine (only with the operator's
'awareness' flag) > joystick (MANUAL mode only) > navigation (AUTO mode only). Which inputs are
admissible this tick (mode, awareness) is the caller's decision, passed to `TwistMux.select`; the mux
itself knows only priorities and times.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable
from dataclasses import dataclass

from atemr.errors import ConfigError
from atemr.msgs import ZERO_TWIST, Twist

#: Default input timeout (docs/navigation.md#twist-mux, docs/testing.md#what-the-robot-promises: as ROS
#: twist_mux and diff_drive_controller).
DEFAULT_TIMEOUT_S = 0.5


@dataclass(frozen=True)
class MuxInput:
    """One velocity source: its name, priority (higher wins) and timeout in seconds."""

    name: str
    priority: int
    timeout_s: float = DEFAULT_TIMEOUT_S


@dataclass(frozen=True)
class MuxResult:
    """What the mux decided: the twist, which input or lock won (None: nothing fresh), and why."""

    twist: Twist
    source: str | None
    locked: bool = False

    @property
    def fresh(self) -> bool:
        """True when a live input or an engaged lock produced the twist (False: the watchdog zero)."""
        return self.source is not None


#: ATEMR's inputs (docs/navigation.md#twist-mux). The safety stop is a lock, above everything.
SAFETY_STOP = "safety_stop"
REACTIVE = "reactive"
JOYSTICK = "joystick"
NAVIGATION = "navigation"


def default_inputs(timeout_s: float = DEFAULT_TIMEOUT_S) -> list[MuxInput]:
    """ATEMR's three velocity inputs in priority order, each with ``timeout_s``."""
    return [MuxInput(REACTIVE, 30, timeout_s), MuxInput(JOYSTICK, 20, timeout_s), MuxInput(NAVIGATION, 10, timeout_s)]


class TwistMux:
    """Keeps the latest command of each input and selects one per tick.

    ``locks`` maps a lock name to its priority; a lock is engaged with `set_lock` and holds until
    released (no timeout: the safety stop must never expire by itself).
    """

    def __init__(self, inputs: Iterable[MuxInput] | None = None, locks: dict[str, int] | None = None) -> None:
        inputs = list(default_inputs() if inputs is None else inputs)
        locks = {SAFETY_STOP: 100} if locks is None else dict(locks)
        names = [i.name for i in inputs] + list(locks)
        if len(set(names)) != len(names):
            raise ConfigError(f"twist mux: input and lock names must be unique, got {names}")
        for i in inputs:
            if not (i.timeout_s > 0.0 and math.isfinite(i.timeout_s)):
                raise ConfigError(f"twist mux: input '{i.name}' needs a positive timeout, got {i.timeout_s!r}")
        # highest priority first; ties keep declaration order
        self.inputs = sorted(inputs, key=lambda i: -i.priority)
        self.locks = dict(locks)
        self._latest: dict[str, tuple[Twist, float]] = {}
        self._engaged: set[str] = set()

    def publish(self, name: str, twist: Twist, t: float) -> None:
        """Record ``twist`` from input ``name`` commanded at time ``t``.

        A non-finite twist is not a command: it is dropped (the input goes stale and times out) rather
        than passed on to the motors.
        """
        if name not in {i.name for i in self.inputs}:
            raise ConfigError(f"twist mux: unknown input '{name}'; inputs: {', '.join(i.name for i in self.inputs)}")
        if math.isfinite(twist.linear_mps) and math.isfinite(twist.angular_radps) and math.isfinite(t):
            self._latest[name] = (twist, t)

    def set_lock(self, name: str, engaged: bool) -> None:
        """Engage or release lock ``name``."""
        if name not in self.locks:
            raise ConfigError(f"twist mux: unknown lock '{name}'; locks: {', '.join(self.locks)}")
        if engaged:
            self._engaged.add(name)
        else:
            self._engaged.discard(name)

    def clear(self, name: str) -> None:
        """Forget input ``name``'s last command (it is absent until it publishes again)."""
        self._latest.pop(name, None)

    def is_fresh(self, name: str, now: float) -> bool:
        """Whether input ``name`` has a command younger than its timeout at ``now``."""
        return self.fresh_command(name, now) is not None

    def fresh_command(self, name: str, now: float) -> Twist | None:
        """Input ``name``'s latest command if still fresh at ``now`` (locks ignored), else None."""
        spec = next((i for i in self.inputs if i.name == name), None)
        latest = self._latest.get(name)
        if spec is None or latest is None or not _fresh(latest[1], now, spec.timeout_s):
            return None
        return latest[0]

    def select(self, now: float, admissible: Collection[str] | None = None) -> MuxResult:
        """The winning command at ``now`` among ``admissible`` inputs (all when None).

        An engaged lock outranking the best fresh input yields zero with the lock as source; nothing
        fresh yields zero with source None (the watchdog case).
        """
        lock_priority, lock_name = max(((self.locks[n], n) for n in self._engaged), default=(-math.inf, None))
        for spec in self.inputs:
            if spec.priority <= lock_priority:
                break
            if admissible is not None and spec.name not in admissible:
                continue
            latest = self._latest.get(spec.name)
            if latest is not None and _fresh(latest[1], now, spec.timeout_s):
                return MuxResult(latest[0], spec.name)
        if lock_name is not None:
            return MuxResult(ZERO_TWIST, lock_name, locked=True)
        return MuxResult(ZERO_TWIST, None)


def _fresh(t: float, now: float, timeout_s: float) -> bool:
    # strictly younger than the timeout: at exactly timeout_s the input is already absent. A command
    # stamped in the future (clock skew) is fresh only until its own time plus the timeout.
    return now - t < timeout_s


__all__ = [
    "DEFAULT_TIMEOUT_S",
    "JOYSTICK",
    "NAVIGATION",
    "REACTIVE",
    "SAFETY_STOP",
    "MuxInput",
    "MuxResult",
    "TwistMux",
    "default_inputs",
]
