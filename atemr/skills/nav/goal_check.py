"""Goal checks before a goal is accepted (docs/agent.md#the-lifecycle, IDLE → EXEC): what a refusal says
is what the operator reads in the agent's Error state, so each reason names the goal and the place.

Checks, in order: finite numbers; AUTO mode; robot localized; inside the map; not in an obstacle (lethal)
nor so close to one that the robot's footprint would touch it (inscribed); not in unknown space (unless
the costmap is told to plan through it). Obstacles are the map's: a person standing on the goal right now
is no reason to refuse it. Whether a *path* exists is the planner's answer, not a check
here: a goal may be valid and unreachable right now (a closed door), which is a navigation failure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from atemr.errors import NavigationError
from atemr.msgs import Pose2D
from atemr.skills.nav.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap

GoalRefusal = Literal["not finite", "not AUTO mode", "not localized", "outside the map", "in an obstacle",
                      "too close to an obstacle", "in unknown space"]


@dataclass(frozen=True)
class GoalCheck:
    """The verdict: ``ok``, or the refusal ``code`` and a sentence for the operator."""

    ok: bool
    code: GoalRefusal | None = None
    reason: str = ""

    def raise_if_refused(self) -> None:
        """`NavigationError` with the reason when the goal was refused."""
        if not self.ok:
            raise NavigationError(self.reason)


def _where(goal: Pose2D) -> str:
    return f"goal ({goal.x_m:.2f}, {goal.y_m:.2f}, {goal.yaw_rad:.2f} rad)"


def check_goal(goal: Pose2D, costmap: Costmap, *, localized: bool = True, mode: str = "AUTO",
               allow_unknown: bool = False) -> GoalCheck:
    """Whether ``goal`` may be accepted now; see the module doc for the order of the checks."""
    values = (goal.x_m, goal.y_m, goal.yaw_rad)
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        return GoalCheck(False, "not finite", f"goal ({goal.x_m}, {goal.y_m}, {goal.yaw_rad}): "
                                              "x, y and yaw must be finite numbers")
    if mode != "AUTO":
        return GoalCheck(False, "not AUTO mode", f"{_where(goal)} refused: the robot is in {mode} mode; "
                                                 "switch to AUTO to send goals")
    if not localized:
        return GoalCheck(False, "not localized", f"{_where(goal)} refused: the robot is not localized; "
                                                 "set its initial pose first")
    m = costmap.map
    row, col, inside = costmap.cells(goal.x_m, goal.y_m)
    if not bool(inside):
        w, h = m.size_m
        ox, oy = m.origin.x_m, m.origin.y_m
        return GoalCheck(False, "outside the map",
                         f"{_where(goal)} is outside the map '{m.name}' "
                         f"(x {ox:.2f}..{ox + w:.2f} m, y {oy:.2f}..{oy + h:.2f} m)")
    cost = int(costmap.static_cost[int(row), int(col)])
    if (m.unknown[int(row), int(col)] or cost == NO_INFORMATION) and not allow_unknown:
        return GoalCheck(False, "in unknown space", f"{_where(goal)} lies in unmapped space of map '{m.name}'")
    if cost == LETHAL:
        return GoalCheck(False, "in an obstacle", f"{_where(goal)} is inside an obstacle of map '{m.name}' "
                                                  f"(cell row {int(row)}, col {int(col)})")
    if cost == INSCRIBED:
        clearance = float(costmap.distance_m[int(row), int(col)])
        return GoalCheck(False, "too close to an obstacle",
                         f"{_where(goal)} is {clearance:.2f} m from an obstacle of map '{m.name}'; the robot needs "
                         f"{costmap.params.inscribed_radius_m:.2f} m")
    return GoalCheck(True)
