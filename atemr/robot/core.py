"""`Robot`: a running robot's configuration, clock, scheduler and named parts, plus its event log."""

from __future__ import annotations

import logging
import threading
from collections import deque
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any

from atemr.clock import Clock
from atemr.config import Config
from atemr.scheduler import Component, Scheduler

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RobotEvent:
    """Something an operator should see: a fault, a refusal, a collision, a component error."""

    t: float
    kind: str
    text: str

    def as_dict(self) -> dict[str, Any]:
        return {"t": self.t, "kind": self.kind, "text": self.text}


@dataclass
class Robot:
    """The assembled robot. Build it with `atemr.robot.build_robot`; parts are reachable by name."""

    config: Config
    clock: Clock
    scheduler: Scheduler
    parts: dict[str, Component] = field(default_factory=dict)
    events: deque[RobotEvent] = field(default_factory=lambda: deque(maxlen=200))
    #: Extra objects that are not scheduled (inputs, health board, simulation, stores), by name.
    extras: dict[str, Any] = field(default_factory=dict)
    _events_lock: threading.Lock = field(default_factory=threading.Lock)

    def add(self, component: Component, rate_hz: float) -> None:
        """Schedule ``component`` and make it reachable as ``robot.parts[name]``."""
        self.scheduler.add(component, rate_hz)
        self.parts[component.name] = component

    def event(self, kind: str, text: str) -> None:
        """Record an event for the dashboard (thread-safe) and log it."""
        with self._events_lock:
            self.events.append(RobotEvent(self.clock.now(), kind, text))
        log.info("%s: %s", kind, text)

    def recent_events(self, n: int = 20) -> list[dict[str, Any]]:
        with self._events_lock:
            return [e.as_dict() for e in list(self.events)[-n:]]

    def start(self) -> None:
        """Start every component in order."""
        self.scheduler.start()
        log.info("started: %s", ", ".join(self.parts))

    def run(self, *, duration: float | None = None, until: float | None = None) -> None:
        """Tick until `stop` is called or up to ``until`` / for ``duration`` seconds of robot time."""
        self.scheduler.run(duration=duration, until=until)

    def stop(self) -> None:
        """Ask `run` to return; safe from a signal handler or another thread."""
        self.scheduler.stop()

    def shutdown(self) -> None:
        """Shut components down in reverse order; idempotent."""
        self.scheduler.shutdown()

    def __enter__(self) -> Robot:
        self.start()
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.shutdown()
