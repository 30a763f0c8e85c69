"""A route given with a goal: the robot drives along these points in order, not the planner's shortest way.

What Nav2's ``FollowPath`` is for: the operator (or a mission author) knows the way it should go (along
the corridor rather than through the dining area, round the side of the bed the carer keeps clear). The
`Navigator` uses a `Route` in place of its global plan: from wherever the robot is, the path it hands the
local planner is the rest of the route, with an A* approach in front when the robot is off the route (at
the start, or pushed aside). Progress along the route only moves forward, so a route that passes the same
place twice is followed in order. A stretch just ahead that the live costmap now blocks is not bypassed
by another way: the navigator waits, runs its recoveries and then fails with "no path", as for a plan.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from atemr.msgs import Pose2D
from atemr.skills.nav.costmap import INSCRIBED, Costmap

FloatArray = NDArray[np.float64]

#: Further off the route than this, the robot first drives to it (planned); closer, it just follows.
JOIN_M = 0.35
#: How far ahead of its progress the robot is matched to the route (a loop back is not a shortcut).
MATCH_WINDOW_M = 1.0


def _arc(points: FloatArray) -> FloatArray:
    seg = np.hypot(*np.diff(points, axis=0).T) if len(points) > 1 else np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(seg)])


@dataclass
class Route:
    """Densified route points (N, 2) in the map frame, ending at the goal, and how far the robot has come."""

    points: FloatArray
    index: int = 0

    @classmethod
    def through(cls, points: Sequence[Sequence[float]], goal: Pose2D, step_m: float) -> Route:
        """The route through ``points`` then the goal's position, with a point every ``step_m`` at most.

        Raises ``ValueError`` (what and which point) for a point that is not two finite numbers.
        """
        raw = []
        for i, point in enumerate(points):
            if len(point) != 2 or not all(math.isfinite(float(v)) for v in point):
                raise ValueError(f"route point {i} must be two finite numbers [x_m, y_m], got {list(point)!r}")
            raw.append((float(point[0]), float(point[1])))
        end = (goal.x_m, goal.y_m)
        if not raw or math.dist(raw[-1], end) > 1e-6:
            raw.append(end)
        corners = np.asarray(raw, dtype=np.float64)
        dense = [corners[:1]]
        for a, b in itertools.pairwise(corners):
            n = max(1, math.ceil(float(np.hypot(*(b - a))) / step_m))
            dense.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
        return cls(np.concatenate(dense))

    def refusal(self, costmap: Costmap) -> str | None:
        """Why the map itself rules the route out (it leaves the map, or runs through or too close to a wall
        or furniture of the map), else None. Only the static layer: a person on the route now is waited for."""
        rows, cols, inside = costmap.cells(self.points[:, 0], self.points[:, 1])
        if not inside.all():
            x, y = self.points[int(np.argmin(inside))]
            return f"route leaves the map near ({x:.2f}, {y:.2f})"
        bad = costmap.static_cost[rows, cols] >= INSCRIBED
        if bad.any():
            x, y = self.points[int(np.argmax(bad))]
            return f"route passes through or too close to an obstacle near ({x:.2f}, {y:.2f})"
        return None

    def advance(self, x_m: float, y_m: float) -> float:
        """Move the progress to the route point nearest ``(x_m, y_m)`` within the match window ahead, when the
        robot is on the route there; return how far the robot is from the route's point at its progress.

        Off the route (not yet on it, or pushed aside) the progress stays put: the robot drives back to where
        it left the route (its first point at the start) and skips nothing.
        """
        rest = self.points[self.index:]
        window = rest[: int(np.searchsorted(_arc(rest), MATCH_WINDOW_M, side="right")) + 1]
        d = np.hypot(window[:, 0] - x_m, window[:, 1] - y_m)
        i = int(np.argmin(d))
        if d[i] > JOIN_M:
            return float(d[0])
        self.index += i
        return float(d[i])

    @property
    def rest(self) -> FloatArray:
        """The route from the robot's progress to the goal."""
        return self.points[self.index:]

    @property
    def length_m(self) -> float:
        return float(_arc(self.points)[-1])
