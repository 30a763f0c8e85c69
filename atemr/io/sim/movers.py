"""Moving obstacles: people walking a path and pets wandering an area.

They are circles (cylinders for the camera). They are polite: a mover whose next step would touch the
robot waits, so a bump with a person is always the robot driving into them, as the collision report
says. Random choices (a pet's next target and pause) come from the injected generator only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.io.sim.scene import Scene
from atemr.io.sim.world import MoverSpec

#: How close a moving person or pet comes to the robot before it stops and waits, in metres.
PERSONAL_SPACE_M = 0.15
#: How long a pet waits for the robot to get out of its way before it wanders off elsewhere, in seconds. A
#: cat does not queue: without this a robot waiting for the pet and the pet waiting for the robot stand in a
#: doorway for ever, which no home shows.
PET_PATIENCE_S = 2.0


@dataclass
class Mover:
    """One moving obstacle's state."""

    spec: MoverSpec
    x_m: float
    y_m: float
    target: int = 1  # index of the path point walked towards
    direction: int = 1  # +1 forwards along the path, -1 backwards (back-and-forth paths)
    goal: tuple[float, float] | None = None  # a pet's current target
    pause_s: float = 0.0
    blocked_s: float = 0.0  # how long the robot has been in its way

    @property
    def name(self) -> str:
        return self.spec.name


class Movers:
    """All moving obstacles of a world, stepped together."""

    def __init__(self, specs: tuple[MoverSpec, ...], scene: Scene, rng: np.random.Generator) -> None:
        self.scene = scene
        self.rng = rng
        self.items: list[Mover] = []
        for spec in specs:
            if spec.kind == "person":
                x, y = spec.path[0]
            else:
                assert spec.area is not None
                x, y = self._random_point(spec)
            self.items.append(Mover(spec, x, y))
        self._sync()

    def _sync(self) -> None:
        self._centres: np.ndarray | None = None
        self.radii = np.array([m.spec.radius_m for m in self.items], dtype=np.float64)
        self.heights = np.array([m.spec.height_m for m in self.items], dtype=np.float64)
        self.colors = np.array([m.spec.color for m in self.items], dtype=np.float64).reshape(-1, 3)

    @property
    def centres(self) -> np.ndarray:
        """(N, 2) positions, built when a sensor asks (not on every physics step)."""
        if self._centres is None:
            self._centres = np.array([(m.x_m, m.y_m) for m in self.items], dtype=np.float64).reshape(-1, 2)
        return self._centres

    def _random_point(self, spec: MoverSpec, away: tuple[float, float, float, float] | None = None,
                      ) -> tuple[float, float]:
        """A point of the area with room for the pet (tries a few, falls back to the area's centre).

        ``away`` (pet x, y, robot x, y) asks for a point on the pet's side, not past the robot it gave way to;
        without one the pet stays where it is.
        """
        assert spec.area is not None
        x0, y0, x1, y1 = spec.area
        for _ in range(20):
            x = float(self.rng.uniform(x0, x1))
            y = float(self.rng.uniform(y0, y1))
            if away is not None:
                px, py, rx, ry = away
                if (x - px) * (rx - px) + (y - py) * (ry - py) > 0:
                    continue
            if self.scene.clearance(x, y, spec.radius_m).clearance_m > 0.02:
                return x, y
        return (away[0], away[1]) if away is not None else ((x0 + x1) / 2, (y0 + y1) / 2)

    def step(self, dt_s: float, robot_xy: tuple[float, float], robot_radius_m: float) -> None:
        """Move every obstacle by ``dt_s`` seconds, waiting where the robot is in the way.

        People and pets keep `PERSONAL_SPACE_M` from the robot: they do not walk into it, so a collision
        the simulator reports is one the robot caused.
        """
        for m in self.items:
            nx, ny = self._next(m, dt_s)
            gap = math.hypot(nx - robot_xy[0], ny - robot_xy[1]) - robot_radius_m - m.spec.radius_m
            now_gap = math.hypot(m.x_m - robot_xy[0], m.y_m - robot_xy[1]) - robot_radius_m - m.spec.radius_m
            if gap < PERSONAL_SPACE_M and gap < now_gap:
                # wait for the robot to get out of the way, as a person would; a pet soon goes elsewhere
                m.blocked_s += dt_s
                if m.spec.kind == "pet" and m.blocked_s >= PET_PATIENCE_S:
                    m.goal = self._random_point(m.spec, away=(m.x_m, m.y_m, *robot_xy))
                    m.blocked_s = 0.0
                continue
            m.blocked_s = 0.0
            m.x_m, m.y_m = nx, ny
        self._centres = None

    def _next(self, m: Mover, dt_s: float) -> tuple[float, float]:
        spec = m.spec
        if spec.kind == "pet":
            if m.pause_s > 0:
                m.pause_s = max(0.0, m.pause_s - dt_s)
                return m.x_m, m.y_m
            if m.goal is None:
                m.goal = self._random_point(spec)
            gx, gy = m.goal
            dist = math.hypot(gx - m.x_m, gy - m.y_m)
            step = spec.speed_mps * dt_s
            if dist <= step:
                m.goal = None
                m.pause_s = float(self.rng.uniform(0.5, 3.0))
                return gx, gy
            nx, ny = m.x_m + (gx - m.x_m) / dist * step, m.y_m + (gy - m.y_m) / dist * step
            if self.scene.clearance(nx, ny, spec.radius_m).clearance_m < 0:
                m.goal = None  # something in the way: pick another target next time
                return m.x_m, m.y_m
            return nx, ny
        # A person walks the path at constant speed, turning at each point.
        remaining = spec.speed_mps * dt_s
        x, y = m.x_m, m.y_m
        n = len(spec.path)
        for _ in range(4 * n):  # bounded: a step never crosses more than a few path points
            tx, ty = spec.path[m.target]
            dist = math.hypot(tx - x, ty - y)
            if dist > remaining:
                return x + (tx - x) / dist * remaining, y + (ty - y) / dist * remaining
            x, y = tx, ty
            remaining -= dist
            if spec.loop:
                m.target = (m.target + 1) % n
            else:
                if not 0 <= m.target + m.direction < n:
                    m.direction = -m.direction
                m.target += m.direction
            if remaining <= 0:
                break
        return x, y
