"""The board's one power button: presses in, gestures out, timed on the injected clock.

The operator's gestures (thesis 3.6.3, "Control-Power Interface") are told apart by how long the button
was held when it is released: under 1 s is a short press (toggle OPS ⇄ CONFIG), 1 s or more powers the
primary on, 5 s or more requests power-off. While it is held the board beeps once per full second, so the
operator can count. Presses come from other threads (dashboard, CLI, terminal), so they are only queued
here and take effect at the next `Button.poll`, on the board's own clock: deterministic in simulation.
"""

from __future__ import annotations

import enum
import threading
from collections import deque
from dataclasses import dataclass

#: Held at least this long (s): power the primary on.
HOLD_POWER_ON_S = 1.0
#: Held at least this long (s): request power-off.
HOLD_POWER_OFF_S = 5.0
# Tolerance on hold durations, so a hold of exactly 1.0 s computed from float tick times still counts.
_EPS = 1e-6


class Gesture(enum.Enum):
    """What a completed press means, by how long the button was held."""

    SHORT = "short press"
    HOLD_1S = "hold 1 s"
    HOLD_5S = "hold 5 s"


def classify(held_s: float) -> Gesture:
    """The gesture of a press held for ``held_s`` seconds."""
    if held_s + _EPS >= HOLD_POWER_OFF_S:
        return Gesture.HOLD_5S
    if held_s + _EPS >= HOLD_POWER_ON_S:
        return Gesture.HOLD_1S
    return Gesture.SHORT


@dataclass(frozen=True)
class ButtonEvent:
    """Something `Button.poll` noticed: a gesture completed, or one more full second held (a beep)."""

    t: float
    gesture: Gesture | None = None
    held_s: float = 0.0
    seconds_held: int = 0


class Button:
    """A momentary switch, pressed and released by method calls from any thread.

    `press` and `release` take effect at the next poll (or at an explicit time ``at`` on the board's clock);
    `hold` is a complete press of a given length, the deterministic way for a test, the CLI or the
    dashboard to ask for "hold 5 s".
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._queue: deque[tuple[str, float | None]] = deque()
        self._pressed_at: float | None = None
        self._release_at: float | None = None
        self._beeps = 0

    # -- input, any thread ---------------------------------------------------------------------
    def press(self, at: float | None = None) -> None:
        """Push the button down (now, or at board time ``at``)."""
        with self._lock:
            self._queue.append(("press", at))

    def release(self, at: float | None = None) -> None:
        """Let the button go (now, or at board time ``at``)."""
        with self._lock:
            self._queue.append(("release", at))

    def hold(self, seconds: float) -> None:
        """Press now and release ``seconds`` later on the board's clock."""
        if not seconds >= 0:
            raise ValueError(f"a hold lasts >= 0 s, got {seconds}")
        with self._lock:
            self._queue.append(("hold", seconds))

    def short_press(self) -> None:
        """Press and release at once: toggles OPS ⇄ CONFIG."""
        self.hold(0.0)

    # -- state ---------------------------------------------------------------------------------
    @property
    def is_pressed(self) -> bool:
        return self._pressed_at is not None

    def held_s(self, now: float) -> float:
        """How long the button has been held at ``now`` (0 when it is up)."""
        return 0.0 if self._pressed_at is None else max(0.0, now - self._pressed_at)

    # -- the board's tick ----------------------------------------------------------------------
    def poll(self, now: float) -> list[ButtonEvent]:  # noqa: PLR0912  one branch per queued input kind (press, release, hold)
        """Apply queued input up to ``now`` and return what happened, in time order."""
        events: list[ButtonEvent] = []
        while True:
            with self._lock:
                if self._release_at is None and self._queue:
                    kind, value = self._queue.popleft()
                else:
                    kind, value = "", None
            if kind == "press":
                if self._pressed_at is None:
                    self._pressed_at = now if value is None else min(value, now)
                    self._beeps = 0
            elif kind == "release":
                if self._pressed_at is not None:
                    events.extend(self._finish(now if value is None else min(value, now)))
            elif kind == "hold":
                if self._pressed_at is None:
                    self._pressed_at = now
                    self._beeps = 0
                    self._release_at = now + float(value or 0.0)
            else:
                break
            if self._release_at is not None:
                break
        if self._release_at is not None and now + _EPS >= self._release_at:
            events.extend(self._finish(self._release_at))
            self._release_at = None
            events.extend(self.poll(now))  # input queued behind the hold
        elif self._pressed_at is not None:
            events.extend(self._beep_until(now))
        return events

    def _beep_until(self, now: float) -> list[ButtonEvent]:
        assert self._pressed_at is not None
        events = []
        while self._pressed_at + self._beeps + 1 <= now + _EPS:
            self._beeps += 1
            events.append(ButtonEvent(self._pressed_at + self._beeps, seconds_held=self._beeps))
        return events

    def _finish(self, released_at: float) -> list[ButtonEvent]:
        assert self._pressed_at is not None
        events = self._beep_until(released_at)
        held = max(0.0, released_at - self._pressed_at)
        self._pressed_at = None
        self._release_at = None
        events.append(ButtonEvent(released_at, gesture=classify(held), held_s=held, seconds_held=self._beeps))
        return events
