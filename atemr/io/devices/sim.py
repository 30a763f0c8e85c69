"""The simulator's sensors behind the device interface (driver ``sim``).

The simulation schedules its own sensor sources (a scan is cast when the world has moved), so a
`SimDevice` is not ticked by the robot (``rate_hz`` None): it passes the source's readings on and judges
freshness by when the source last ticked, on the robot's clock, as a real driver's health does by arrivals. A
camera nobody watches ticks without rendering (`atemr.io.sim.simulation.FrameSource`) and is still healthy;
the device does not subscribe to the source itself, which would count as a consumer of every frame.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

from atemr.domain.status import ComponentHealth
from atemr.io.devices.base import DeviceInfo, fresh
from atemr.io.sim.simulation import PeriodicSource

R = TypeVar("R")


class SimDevice(Generic[R]):
    """A simulated lidar, IMU or camera: one of the simulation's `PeriodicSource`s seen as a `Device`."""

    rate_hz: float | None = None

    def __init__(self, kind: str, source: PeriodicSource[R], *, max_age_s: float,
                 what: str, world: str) -> None:
        self.name = kind
        self.kind = kind
        self.source = source
        self.max_age_s = max_age_s
        self.what = what
        self.world = world

    @property
    def latest(self) -> R | None:
        return self.source.latest

    @property
    def count(self) -> int:
        return self.source.count

    def subscribe(self, callback: Callable[[R], None]) -> None:
        self.source.subscribe(callback)

    def health(self, now: float) -> ComponentHealth:
        return fresh(self.source.last_tick_t, now, self.max_age_s, self.what)

    def info(self) -> DeviceInfo:
        return DeviceInfo(kind=self.kind, driver="sim", model=f"simulated, world {self.world}")

    def tick(self, now: float) -> None:
        """Nothing to do: the simulation ticks the source."""
