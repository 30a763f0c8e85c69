"""Time, injected: the wall clock on the robot, a simulated clock in simulation and tests.

Nothing else in the package reads the wall clock or sleeps; that is what makes a simulation
repeatable and lets it run many times faster than real time.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable

#: Slack in `due`, s: far below any period the robot uses, far above the rounding of summed tick times.
DUE_SLACK_S = 1e-9


def due(now: float, t: float) -> bool:
    """Whether the moment ``t`` has come at ``now``.

    With a little slack (`DUE_SLACK_S`) because times are sums of floats: a 0.05 s period ticked at 50 Hz
    has its deadline land a rounding error after the tick meant to meet it, and without the slack the
    action would run one tick late. Every periodic action and timeout uses this one test, so they agree.
    """
    return now + DUE_SLACK_S >= t


@runtime_checkable
class Clock(Protocol):
    """A monotonic source of seconds that can also wait until a moment."""

    def now(self) -> float:
        """Seconds since an arbitrary, fixed origin; never goes backwards."""
        ...

    def sleep_until(self, t: float) -> None:
        """Return once ``now() >= t``: waits on a wall clock, jumps on a simulated one."""
        ...


class WallClock:
    """Real time, for the robot and for simulations locked to real time."""

    def __init__(self) -> None:
        self._origin = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._origin

    def sleep_until(self, t: float) -> None:
        delay = t - self.now()
        if delay > 0:
            time.sleep(delay)

    def wall_time(self) -> float:
        """Seconds since the epoch, for timestamps that a person reads (file names, logs)."""
        return time.time()


class SimClock:
    """Simulated time that moves only when told to.

    ``sleep_until`` jumps straight to the requested time, so a scheduler driven by this clock runs as
    fast as the CPU allows; ``advance`` moves time by hand in tests.
    """

    def __init__(self, start: float = 0.0) -> None:
        self._t = float(start)

    def now(self) -> float:
        return self._t

    def sleep_until(self, t: float) -> None:
        if t > self._t:
            self._t = float(t)

    def advance(self, dt: float) -> float:
        """Move time forward by ``dt`` seconds (``dt >= 0``) and return the new time."""
        if dt < 0:
            raise ValueError(f"a clock cannot go backwards (dt={dt})")
        self._t += dt
        return self._t


class RealTimeSimClock(SimClock):
    """Simulated time paced against the wall clock (``./run``): one simulated second per real second
    times ``speed``. The simulated time stays exact (ticks land on their nominal times); only the waiting
    is real."""

    def __init__(self, speed: float = 1.0, start: float = 0.0) -> None:
        super().__init__(start)
        if speed <= 0:
            raise ValueError(f"speed must be > 0, got {speed}")
        self.speed = speed
        self._wall = WallClock()
        self._wall_origin = self._wall.now()
        self._sim_origin = float(start)

    def sleep_until(self, t: float) -> None:
        if t <= self._t:
            return
        wall_target = self._wall_origin + (t - self._sim_origin) / self.speed
        self._wall.sleep_until(wall_target)
        self._t = float(t)
