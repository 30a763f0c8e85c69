"""The one place where the robot is wired: which components exist, at what rate, on which clock.

Everything else is a part; `build_robot` assembles the parts from a `Config`. The same wiring runs on
the real robot (wall clock, socketcan) and in simulation (simulated clock, virtual bus).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from types import TracebackType

from atemr.clock import Clock, RealTimeSimClock, SimClock, WallClock
from atemr.config import Config
from atemr.io.system_monitor import SystemMonitor
from atemr.scheduler import Component, Scheduler

log = logging.getLogger(__name__)

#: Tick rates of the robot's periodic work, in Hz.
RATES = {
    "system_monitor": 1.0,
}


def make_clock(config: Config, *, realtime: bool) -> Clock:
    """The clock for this run: wall clock on the robot; simulated, paced or not, in simulation."""
    if not config.simulation:
        return WallClock()
    return RealTimeSimClock(speed=config.sim.speed) if realtime else SimClock()


@dataclass
class Robot:
    """A running robot: its configuration, clock, scheduler and components (in start order)."""

    config: Config
    clock: Clock
    scheduler: Scheduler
    parts: dict[str, Component] = field(default_factory=dict)

    def add(self, component: Component, rate_hz: float) -> None:
        """Schedule ``component`` and make it reachable as ``robot.parts[name]``."""
        self.scheduler.add(component, rate_hz)
        self.parts[component.name] = component

    def start(self) -> None:
        """Start every component in order."""
        self.scheduler.start()
        log.info("started: %s", ", ".join(self.parts))

    def run(self, *, duration: float | None = None) -> None:
        """Tick until `stop` is called or ``duration`` seconds of robot time have passed."""
        self.scheduler.run(duration=duration)

    def stop(self) -> None:
        """Ask `run` to return; safe from a signal handler."""
        self.scheduler.stop()

    def shutdown(self) -> None:
        """Shut components down in reverse order; idempotent."""
        self.scheduler.shutdown()

    def __enter__(self) -> Robot:
        self.start()
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.shutdown()


def build_robot(config: Config, *, realtime: bool = True, clock: Clock | None = None) -> Robot:
    """Assemble the robot described by ``config``.

    ``realtime`` paces a simulation against the wall clock (what ``./run`` does); without it the
    simulation runs as fast as the CPU allows. ``clock`` overrides both (tests).
    """
    clock = clock or make_clock(config, realtime=realtime)
    robot = Robot(config, clock, Scheduler(clock))
    robot.add(SystemMonitor(config.data_dir), RATES["system_monitor"])
    return robot
