"""Component health as the agent and the dashboard see it: one place that decides what "OK" means.

A sensor is healthy while it publishes fresh data; a motor while it answers and has no fault; the web
server while it is serving. Names follow the 0x153 hardware bits (`atemr.trees.ports.HARDWARE_COMPONENTS`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from atemr.trees.ports import ComponentHealth

#: How old a sensor's newest reading may be before the sensor counts as silent, in seconds.
FRESH_S = {"lidar": 0.5, "imu": 0.2, "camera": 1.0, "ir": 0.5}


def fresh(t: float | None, now: float, max_age_s: float, what: str) -> ComponentHealth:
    """Healthy when a reading from time ``t`` is at most ``max_age_s`` old at ``now``."""
    if t is None:
        return ComponentHealth(False, f"no {what} yet")
    age = now - t
    if not math.isfinite(age) or age > max_age_s:
        return ComponentHealth(False, f"{what} silent for {age:.1f} s")
    return ComponentHealth(True)


@dataclass
class HealthBoard:
    """Named health probes, each a function of ``now``; `collect` evaluates them all."""

    now: Callable[[], float]
    probes: dict[str, Callable[[float], ComponentHealth]] = field(default_factory=dict)

    def add(self, name: str, probe: Callable[[float], ComponentHealth]) -> None:
        self.probes[name] = probe

    def collect(self) -> dict[str, ComponentHealth]:
        now = self.now()
        out: dict[str, ComponentHealth] = {}
        for name, probe in self.probes.items():
            try:
                out[name] = probe(now)
            except Exception as exc:  # a probe that fails reports its component as unhealthy
                out[name] = ComponentHealth(False, f"health probe failed: {exc}")
        return out
