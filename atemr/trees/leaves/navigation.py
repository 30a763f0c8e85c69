"""Navigation leaves: go to a pose through the `NavigationPort` (planners, costmap, recoveries live behind
it), and relocalize through the robot port."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import py_trees

from atemr.errors import AtemrError
from atemr.msgs import ZERO_TWIST
from atemr.trees.behaviours import Leaf, behaviours
from atemr.trees.params import PoseParams

Status = py_trees.common.Status


@behaviours.register("GoToPose")
class GoToPose(Leaf):
    """Drive to ``(x_m, y_m, yaw_rad)`` in the map frame.

    ``initialise`` starts the goal (a refusal is this leaf's FAILURE with the navigator's reason); each
    ``update`` ticks navigation and commands its twist on the mux's navigation input; SUCCESS when the goal
    is reached within the navigator's tolerances, FAILURE with the reason (no path, stuck, localization lost,
    timeout). Interrupted (cancel, timeout decorator, a state change) it cancels the goal; it always leaves
    a zero twist behind.
    """

    Params = PoseParams
    summary = "drive to a pose in the map with navigation"

    def initialise(self) -> None:
        self._started = False
        self._refusal = ""
        navigation = self.ctx.navigation
        if navigation is None:
            self._refusal = "navigation is not available on this robot"
            return
        try:
            navigation.start(self.params.pose(), self.ctx.now)
        except AtemrError as exc:
            self._refusal = f"goal refused: {exc}"
            return
        self._started = True

    def update(self) -> py_trees.common.Status:
        if not self._started or self.ctx.navigation is None:
            return self.fail(self._refusal or "navigation did not start")
        progress = self.ctx.navigation.update(self.ctx.now)
        if progress.state == "RUNNING":
            self.ctx.port.command_velocity("navigation", progress.twist, self.ctx.now)
            left = "" if math.isnan(progress.distance_left_m) else f"{progress.distance_left_m:.2f} m left"
            eta = "" if math.isnan(progress.eta_s) else f", ETA {progress.eta_s:.0f} s"
            self.feedback_message = left + eta
            return Status.RUNNING
        self._started = False
        self.ctx.port.command_velocity("navigation", ZERO_TWIST, self.ctx.now)
        if progress.state == "SUCCEEDED":
            self.feedback_message = "reached"
            return Status.SUCCESS
        return self.fail(f"navigation {progress.state.lower()}: {progress.reason or 'no reason given'}")

    def terminate(self, new_status: py_trees.common.Status) -> None:
        if self._context is None:
            return
        navigation = self.ctx.navigation
        if new_status == Status.INVALID and getattr(self, "_started", False) and navigation is not None:
            navigation.cancel(self.ctx.now)
            self._started = False
        self.ctx.port.command_velocity("navigation", ZERO_TWIST, self.ctx.now)


@dataclass(frozen=True)
class RelocalizeParams:
    timeout_s: float = field(default=30.0, metadata={"min": 0.1, "max": 600.0})


@behaviours.register("Relocalize")
class Relocalize(Leaf):
    """Start global relocalization and wait until the robot is localized again (FAILURE after ``timeout_s``).

    For a robot that knows it is lost (the covariance monitor) or was moved by hand; the base does not move
    by itself here, the localization converges from what the lidar sees (or while a mission's Rotate turns).
    """

    Params = RelocalizeParams
    summary = "relocalize globally on the active map, wait until localized"

    def initialise(self) -> None:
        self._deadline = self.ctx.now + self.params.timeout_s
        self._refusal = ""
        try:
            self.ctx.port.relocalize(self.ctx.now)
        except AtemrError as exc:
            self._refusal = f"cannot relocalize: {exc}"

    def update(self) -> py_trees.common.Status:
        if self._refusal:
            return self.fail(self._refusal)
        if self.ctx.port.localized():
            self.feedback_message = "localized"
            return Status.SUCCESS
        if self.ctx.now >= self._deadline - 1e-9:
            return self.fail(f"not localized after {self.params.timeout_s:g} s")
        self.feedback_message = "relocalizing"
        return Status.RUNNING
