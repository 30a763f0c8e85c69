"""Component health as the agent and the dashboard see it: one place that decides what "OK" means.

A sensor is healthy while it publishes fresh data; a motor while it answers and has no fault; the web
server while it is serving. Names follow the 0x153 hardware bits (`atemr.trees.ports.HARDWARE_COMPONENTS`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from atemr.domain.status import ComponentHealth

#: How old the secondary core's newest IR frame may be before the cliff sensors count as silent, in seconds
#: (the lidar, IMU and camera judge their own freshness: `atemr.io.devices`).
FRESH_S = {"ir": 0.5}


@dataclass
class HealthBoard:
    """Named health probes, each a function of ``now``; `collect` evaluates them all.

    ``recoveries`` clear what a part latched once its cause is gone (the motor driver's fault); the agent's
    Error state runs them through `clear_faults` (`RobotPort.clear_faults`) while it waits.
    """

    now: Callable[[], float]
    probes: dict[str, Callable[[float], ComponentHealth]] = field(default_factory=dict)
    recoveries: dict[str, Callable[[], str | None]] = field(default_factory=dict)

    def add(self, name: str, probe: Callable[[float], ComponentHealth]) -> None:
        self.probes[name] = probe

    def add_recovery(self, name: str, clear: Callable[[], str | None]) -> None:
        """``clear()`` clears what ``name`` latched if its cause is gone: None when nothing stays latched, else why."""
        self.recoveries[name] = clear

    def clear_faults(self) -> str | None:
        """Run every recovery; None when nothing stays latched, else each one's reason (a recovery that raises
        reports that as its reason)."""
        reasons = []
        for name, clear in self.recoveries.items():
            try:
                why = clear()
            except Exception as exc:
                why = f"clearing failed: {exc}"
            if why:
                reasons.append(f"{name}: {why}")
        return "; ".join(reasons) or None

    def collect(self) -> dict[str, ComponentHealth]:
        now = self.now()
        out: dict[str, ComponentHealth] = {}
        for name, probe in self.probes.items():
            try:
                out[name] = probe(now)
            except Exception as exc:  # a probe that fails reports its component as unhealthy
                out[name] = ComponentHealth(False, f"health probe failed: {exc}")
        return out
