"""`Robot`: a running robot's configuration, clock, scheduler and named parts, plus its event log."""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType

import can

from atemr.clock import Clock
from atemr.config import Config
from atemr.io.can.bus import open_bus
from atemr.io.devices.drivers import Devices
from atemr.robot.parts import RobotParts
from atemr.scheduler import Component, Scheduler
from atemr.ui.state import EventJson

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RobotEvent:
    """Something an operator should see: a fault, a refusal, a collision, a component error."""

    t: float
    kind: str
    text: str
    #: The wall-clock time it happened (Unix seconds): what the carer's Events list shows. Robot time ``t`` is
    #: what the trace and the agent go by; in a simulation running faster than real time the two part ways.
    unix_s: float = 0.0

    def as_dict(self) -> EventJson:
        return {"t": self.t, "kind": self.kind, "text": self.text, "unix_s": self.unix_s}


class Ticker:
    """A named scheduler component that calls ``fn(now)`` each tick: glue between two parts."""

    def __init__(self, name: str, fn: Callable[[float], None]) -> None:
        self.name = name
        self.fn = fn

    def tick(self, now: float) -> None:
        self.fn(now)


@dataclass
class Robot:
    """The assembled robot. Build it with `atemr.robot.build_robot`: its parts are ``robot.parts`` (typed) and
    its scheduled components ``robot.components`` (by name)."""

    config: Config
    clock: Clock
    scheduler: Scheduler
    #: The scheduled components by name (``robot.components["agent"]``), in the order they tick.
    components: dict[str, Component] = field(default_factory=dict)
    events: deque[RobotEvent] = field(default_factory=lambda: deque(maxlen=200))
    #: CAN buses opened for the parts; closed after every part has shut down.
    buses: list[can.BusABC] = field(default_factory=list)
    #: Called with ``(t, kind, text)`` for every event, on the thread that raised it (the recorder queues them).
    event_listeners: list[Callable[[float, str, str], None]] = field(default_factory=list)
    #: The wall clock events are stamped with for the dashboard (never for the trace, which stays seeded).
    wall_clock: Callable[[], float] = time.time
    _parts: RobotParts | None = None
    _events_lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def parts(self) -> RobotParts:
        """Everything wired, typed (`atemr.robot.parts.RobotParts`); set by `build_robot`."""
        if self._parts is None:
            raise RuntimeError("the robot's parts are not wired yet (build it with atemr.robot.build_robot)")
        return self._parts

    @parts.setter
    def parts(self, parts: RobotParts) -> None:
        self._parts = parts

    @property
    def devices(self) -> Devices:
        """The lidar, IMU and camera (`atemr.io.devices.drivers.Devices`)."""
        return self.parts.devices

    def add(self, component: Component, rate_hz: float) -> None:
        """Schedule ``component`` and make it reachable as ``robot.components[name]``."""
        self.scheduler.add(component, rate_hz)
        self.components[component.name] = component

    def event(self, kind: str, text: str) -> None:
        """Record an event for the dashboard (thread-safe) and log it."""
        event = RobotEvent(self.clock.now(), kind, text, round(self.wall_clock(), 3))
        with self._events_lock:
            self.events.append(event)
        log.info("%s: %s", kind, text)
        for listener in self.event_listeners:
            listener(event.t, kind, text)

    def recent_events(self, n: int = 20) -> list[EventJson]:
        with self._events_lock:
            return [e.as_dict() for e in list(self.events)[-n:]]

    def start(self) -> None:
        """Start every component in order."""
        self.scheduler.start()
        log.info("started: %s", ", ".join(self.components))

    def run(self, *, duration: float | None = None, until: float | None = None) -> None:
        """Tick until `stop` is called or up to ``until`` / for ``duration`` seconds of robot time."""
        self.scheduler.run(duration=duration, until=until)

    def stop(self) -> None:
        """Ask `run` to return; safe from a signal handler or another thread. Asked while the robot is not
        running, it holds for the next `run`, which returns at once (`Scheduler.stop`)."""
        self.scheduler.stop()

    def open_bus(self) -> can.BusABC:
        """A new Bus on the robot's channel for one participant; the robot closes it at shutdown."""
        bus = open_bus(self.config.can)
        self.buses.append(bus)
        return bus

    def shutdown(self) -> None:
        """Shut components down in reverse order, then close the buses; idempotent."""
        self.scheduler.shutdown()
        self.close_buses()

    def close_buses(self) -> None:
        """Close every bus opened for the parts (after they have shut down, or when building failed)."""
        while self.buses:
            bus = self.buses.pop()
            try:
                bus.shutdown()
            except Exception:
                log.exception("closing a CAN bus failed")

    def __enter__(self) -> Robot:
        self.start()
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.shutdown()
