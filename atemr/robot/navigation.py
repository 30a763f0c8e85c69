"""The agent's `NavigationPort` over the `Navigator` skill, fed by localization and the lidar.

The port owns one `Navigator` on the active map (rebuilt when the map service switches maps), feeds it
the localized pose, the latest scan and the localization flag each agent tick, and keeps the latest
status so the dashboard can draw the global path, the local trajectory and the goal.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from atemr.errors import NavigationError
from atemr.io.sim.maps import OccupancyMap
from atemr.msgs import LaserScan, Pose2D, Twist
from atemr.robot.mapping import MapService
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.nav.navigator import Navigator, NavParams, NavStatus
from atemr.trees.ports import NavProgress


class NavigationPortImpl:
    """`atemr.trees.ports.NavigationPort` over a `Navigator` (see the module docstring)."""

    def __init__(self, maps: MapService, localization: LocalizationPipeline,
                 scan: Callable[[], LaserScan | None], velocity: Callable[[], Twist | None],
                 params: NavParams | None = None) -> None:
        self.localization = localization
        self.scan = scan
        self.velocity = velocity
        self.params = params or NavParams()
        self.navigator: Navigator | None = None
        self.latest: NavStatus | None = None
        self._lock = threading.Lock()
        if maps.active is not None:
            self._use_map(maps.active)
        maps.on_map_change(self._use_map)

    def _use_map(self, grid: OccupancyMap) -> None:
        with self._lock:
            if self.navigator is None:
                self.navigator = Navigator(grid, self.params)
            else:
                self.navigator.set_map(grid)

    def _need(self) -> Navigator:
        if self.navigator is None:
            raise NavigationError("no active map: select or build a map before sending goals")
        return self.navigator

    def check_goal(self, goal: Pose2D) -> str | None:
        try:
            navigator = self._need()
        except NavigationError as exc:
            return str(exc)
        verdict = navigator.check(goal, localized=self.localization.localized)
        return None if verdict.ok else verdict.reason

    def start(self, goal: Pose2D, now: float) -> None:
        with self._lock:
            self._need().start(goal, now, localized=self.localization.localized)
            self.latest = None

    def update(self, now: float) -> NavProgress:
        with self._lock:
            navigator = self._need()
            pose = self.localization.map_pose()
            localized = pose is not None and self.localization.localized
            status = navigator.update(now, pose or Pose2D(float("nan"), float("nan"), float("nan")),
                                      self.scan(), localized, self.velocity())
            self.latest = status
        return NavProgress(status.state, status.twist, status.distance_left_m, status.eta_s, status.message)

    def cancel(self, now: float) -> None:
        with self._lock:
            if self.navigator is not None:
                self.latest = self.navigator.cancel(now)

    @property
    def goal(self) -> Pose2D | None:
        """The goal being pursued (or last pursued), for the dashboard."""
        return None if self.navigator is None else self.navigator.goal
