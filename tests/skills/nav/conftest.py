"""Navigation test helpers: small hand-made grids and a closed loop with the simulator.

The closed loop: the Navigator drives the simulator's base (RMD wheel models, wheel slip) with the
ground-truth pose and the simulated lidar, on a simulated clock, ticking at 10 Hz.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.domain.maps import OccupancyMap
from atemr.io.sim.simulation import Simulation
from atemr.msgs import Pose2D
from atemr.scheduler import Scheduler
from atemr.skills.nav.navigator import Navigator, NavStatus


def grid_map(data: Any, resolution_m: float = 0.05, origin: Pose2D | None = None) -> OccupancyMap:
    """An `OccupancyMap` from a small array (row 0 at the bottom, as ROS)."""
    return OccupancyMap(np.asarray(data, dtype=np.int8), resolution_m, origin or Pose2D(0.0, 0.0, 0.0), name="test")


def room(rows: int = 60, cols: int = 80) -> np.ndarray:
    """A free room with a one-cell wall all round."""
    data = np.zeros((rows, cols), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    return data


@dataclass
class Drive:
    """What happened: the final status, when the run ended, collisions, and every tick's status."""

    status: NavStatus
    t_end: float
    collisions: list[Any]
    statuses: list[NavStatus] = field(default_factory=list)
    #: For each collision, the linear speed the navigator was commanding just before it (≈ 0: the robot
    #: stood still and a person or pet walked into it — the simulator counts that as a contact too).
    commanded_at_contact: list[float] = field(default_factory=list)


class NavComponent:
    """Ticks the navigator and commands the base's wheels with its twist."""

    def __init__(self, sim: Simulation, nav: Navigator, on_tick: Callable[[float, Simulation], None] | None) -> None:
        self.name = "nav"
        self.sim = sim
        self.nav = nav
        self.on_tick = on_tick
        self.status: NavStatus | None = None
        self.statuses: list[NavStatus] = []
        self.commanded_at_contact: list[float] = []

    def tick(self, now: float) -> None:
        if self.on_tick is not None:
            self.on_tick(now, self.sim)
        while len(self.commanded_at_contact) < len(self.sim.collisions):
            self.commanded_at_contact.append(self.status.twist.linear_mps if self.status else 0.0)
        status = self.nav.update(now, self.sim.pose, self.sim.lidar_source.latest, True)
        self.sim.command_twist(status.twist.linear_mps, status.twist.angular_radps)
        self.status = status
        self.statuses.append(status)


def drive(sim: Simulation, nav: Navigator, goal: Pose2D, *, max_s: float = 120.0,
          on_tick: Callable[[float, Simulation], None] | None = None) -> Drive:
    """Start ``goal`` at t = 0 and run until the navigator finishes or ``max_s`` simulated seconds pass."""
    sched = Scheduler(SimClock())
    sim.attach(sched)
    comp = NavComponent(sim, nav, on_tick)
    nav.start(goal, 0.0)
    sched.add(comp, 10.0, phase_s=0.005)
    t = 0.0
    while t < max_s:
        sched.run(duration=1.0)
        t += 1.0
        if comp.status is not None and comp.status.state != "RUNNING":
            break
    assert comp.status is not None
    return Drive(comp.status, t, list(sim.collisions), comp.statuses, comp.commanded_at_contact)


@pytest.fixture
def make_map() -> Callable[..., OccupancyMap]:
    return grid_map


@pytest.fixture
def make_room() -> Callable[..., np.ndarray]:
    return room


@pytest.fixture
def closed_loop() -> Callable[..., Drive]:
    return drive
