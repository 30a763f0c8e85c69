"""What the board does that a person would see or hear: buzzer, LED, screen changes, emergencies.

The real board beeps and lights its button; the emulator turns those into `BoardEvent`s, logged and kept
in a short history for the dashboard's simulation panel and for tests.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

log = logging.getLogger("secondary_core")

EventKind = Literal["buzzer", "led", "screen", "emergency", "button", "portal", "wifi", "can"]


@dataclass(frozen=True)
class BoardEvent:
    """One thing that happened on the board at board time ``t``."""

    t: float
    kind: EventKind
    message: str

    def __str__(self) -> str:
        return f"{self.t:9.3f} {self.kind:<9} {self.message}"


class EventLog:
    """The last ``maxlen`` events, plus listeners called for each new one (a listener's error is logged,
    never raised into the board's tick)."""

    def __init__(self, maxlen: int = 500) -> None:
        self.events: deque[BoardEvent] = deque(maxlen=maxlen)
        self.listeners: list[Callable[[BoardEvent], None]] = []

    def emit(self, t: float, kind: EventKind, message: str) -> BoardEvent:
        event = BoardEvent(t, kind, message)
        self.events.append(event)
        log.info("%s: %s", kind, message)
        for listener in list(self.listeners):
            try:
                listener(event)
            except Exception:
                log.exception("board event listener %r failed", listener)
        return event

    def recent(self, n: int) -> list[BoardEvent]:
        """The last ``n`` events; safe to call from another thread (the copy is taken in one C call)."""
        return list(self.events.copy())[-n:] if n > 0 else []

    def of_kind(self, kind: EventKind) -> list[BoardEvent]:
        return [e for e in self.events.copy() if e.kind == kind]
