"""`Robot`: a running robot's configuration, clock, scheduler and named parts, plus its event log."""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any

import can

from atemr.clock import Clock
from atemr.config import Config
from atemr.io.can.bus import open_bus
from atemr.io.devices.drivers import Devices
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


class Ticker:
    """A named scheduler component that calls ``fn(now)`` each tick: glue between two parts."""

    def __init__(self, name: str, fn: Callable[[float], None]) -> None:
        self.name = name
        self.fn = fn

    def tick(self, now: float) -> None:
        self.fn(now)


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
    #: CAN buses opened for the parts; closed after every part has shut down.
    buses: list[can.BusABC] = field(default_factory=list)
    #: The sensors behind the device interface; set by `build_robot` before anything reads them.
    _devices: Devices | None = None
    _events_lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def devices(self) -> Devices:
        """The lidar, IMU and camera (`atemr.io.devices.drivers.Devices`)."""
        if self._devices is None:
            raise RuntimeError("the robot's devices are not built yet")
        return self._devices

    @devices.setter
    def devices(self, devices: Devices) -> None:
        self._devices = devices

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

    def open_bus(self) -> can.BusABC:
        """A new Bus on the robot's channel for one participant; the robot closes it at shutdown."""
        bus = open_bus(self.config.can)
        self.buses.append(bus)
        return bus

    def shutdown(self) -> None:
        """Shut components down in reverse order, then close the buses; idempotent."""
        self.scheduler.shutdown()
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
