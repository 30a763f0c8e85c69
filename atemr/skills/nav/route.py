"""A route given with a goal: the robot drives along these points in order, not the planner's shortest way.

What Nav2's ``FollowPath`` is for: the operator (or a mission author) knows the way it should go (along
the corridor rather than through the dining area, round the side of the bed the carer keeps clear). The
`Navigator` follows a `Route` in place of its global plan. Every tick the robot's progress along the route
moves forward (`Route.advance`: from the progress point, on while the route comes nearer to the robot, so a
route that passes the same place twice, or turns back in a hairpin, is followed in order), and the local
planner is handed the stretch just ahead (`Route.window`: up to a few metres, ending where the route comes
back near itself). Off the route (at the start, or pushed aside) the robot first drives back to its progress
point by an A* approach; nothing is skipped. A stretch just ahead that the live costmap now blocks is not
bypassed another way: the navigator waits, runs its recoveries and then fails with "no path", as for a plan.
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
from atemr.skills.nav.local_planner import arc_lengths

FloatArray = NDArray[np.float64]

#: Further off the route than this, the robot first drives to it (planned); closer, it just follows.
JOIN_M = 0.35
#: Longest walk of the progress along the route in one call (a tick): far more than the base covers in one
#: (1.6 m/s at 10 Hz), far less than a later pass of the same place, which it must never jump to.
MAX_WALK_M = 0.5
#: Longest stretch of the route handed to the local planner.
WINDOW_M = 2.0
#: The window ends where the route comes back within this distance of a point it passed ...
REVISIT_M = JOIN_M + 0.1
#: ... at least this much earlier along it (a hairpin, a loop): the later pass must not look like the way on.
REVISIT_ARC_M = 0.5


@dataclass
class Route:
    """Densified route points (N, 2) in the map frame, ending at the goal, and how far the robot has come."""

    points: FloatArray
    #: Cumulative length along the route at each point.
    arc: FloatArray
    index: int = 0

    @classmethod
    def through(cls, points: Sequence[Sequence[float]], goal: Pose2D, step_m: float) -> Route:
        """The route through ``points`` then the goal's position, with a point every ``step_m`` at most.

        Raises ``ValueError`` (what and which point) for a point that is not two finite numbers.
        """
        raw = []
        for i, point in enumerate(points):
            try:
                x, y = (float(v) for v in point)
                finite = math.isfinite(x) and math.isfinite(y)
            except (TypeError, ValueError):
                finite = False
            if not finite:
                raise ValueError(f"route point {i} must be two finite numbers [x_m, y_m], got {point!r}")
            raw.append((x, y))
        end = (goal.x_m, goal.y_m)
        if not raw or math.dist(raw[-1], end) > 1e-6:
            raw.append(end)
        corners = np.asarray(raw, dtype=np.float64)
        dense = [corners[:1]]
        for a, b in itertools.pairwise(corners):
            n = max(1, math.ceil(float(np.hypot(*(b - a))) / step_m))
            dense.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
        dense_points = np.concatenate(dense)
        return cls(dense_points, arc_lengths(dense_points))

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
        """Move the progress on along the route while the route comes nearer to ``(x_m, y_m)``, when the robot
        is on the route there; return how far the robot is from the route's point at its progress.

        Walking on only while the distance falls, and at most `MAX_WALK_M`, stops at the first stretch near the
        robot, never at a later pass of the same place. Off the route (not yet on it, or pushed aside) the
        progress stays put: the robot drives back to where it left the route (its first point at the start), so
        nothing is skipped.
        """
        here = self.points[self.index]
        best = math.hypot(here[0] - x_m, here[1] - y_m)
        i = self.index
        limit = self.arc[self.index] + MAX_WALK_M
        while i + 1 < len(self.points) and self.arc[i + 1] <= limit:
            d = math.hypot(self.points[i + 1, 0] - x_m, self.points[i + 1, 1] - y_m)
            if d > best + 1e-9:
                break
            i, best = i + 1, d
        if best > JOIN_M:
            return math.hypot(here[0] - x_m, here[1] - y_m)
        self.index = i
        return best

    def window(self, length_m: float = WINDOW_M) -> FloatArray:
        """The route from the progress point on, at most ``length_m`` long, ending before it comes back near a
        point it passed (within `REVISIT_M` of one at least `REVISIT_ARC_M` earlier): what the local planner
        follows, so it never mistakes a later pass of the same place for the way on."""
        end = max(int(np.searchsorted(self.arc, self.arc[self.index] + length_m, side="right")), self.index + 2)
        ahead, along = self.points[self.index:end], self.arc[self.index:end]
        if len(ahead) > 2:
            near = np.hypot(ahead[:, None, 0] - ahead[None, :, 0], ahead[:, None, 1] - ahead[None, :, 1]) < REVISIT_M
            later = (along[None, :] - along[:, None]) > REVISIT_ARC_M  # [i, j]: j passed after i
            back = np.flatnonzero((near & later).any(axis=0))
            if len(back):
                ahead = ahead[:int(back[0])]
        return ahead

    @property
    def remaining_m(self) -> float:
        """Length of the route still to drive, from the progress point to the goal."""
        return float(self.arc[-1] - self.arc[self.index])

    @property
    def rest(self) -> FloatArray:
        """The route from the robot's progress to the goal."""
        return self.points[self.index:]

    @property
    def length_m(self) -> float:
        return float(self.arc[-1])
