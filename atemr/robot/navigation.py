"""Navigation on the robot: the agent's `NavigatorPort` over one `Navigator`, kept on the active map.

`atemr.robot.navigator_port.NavigatorPort` adapts a `Navigator` to the agent's `NavigationPort`; this
module gives it its inputs on the robot (the localized map pose, the latest scan, the localization flag,
the measured twist) and gives the navigator each new map's costmap, prepared off the robot's thread when
the map service switches maps (`atemr.robot.mapping.MapUser`).
"""

from __future__ import annotations

from collections.abc import Callable

from atemr.domain.maps import OccupancyMap
from atemr.msgs import LaserScan, Pose2D, Twist
from atemr.robot.mapping import MapService
from atemr.robot.navigator_port import NavigatorPort
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.nav.navigator import Navigator, NavMap, NavParams


class RobotNavigation(NavigatorPort):
    """The robot's `NavigationPort`; ``last_status`` and ``goal`` feed the dashboard's paths and goal marker."""

    def __init__(self, maps: MapService, localization: LocalizationPipeline,
                 scan: Callable[[], LaserScan | None], velocity: Callable[[], Twist | None],
                 params: NavParams | None = None) -> None:
        super().__init__(None, pose=localization.map_pose, scan=scan, localized=lambda: localization.localized,
                         velocity=velocity)
        self.params = params
        if maps.active is not None:
            self.use_map(maps.active, None)
        maps.add_map_user(self)

    # -- the map service's MapUser -------------------------------------------------------------------
    def prepare_map(self, grid: OccupancyMap) -> NavMap:
        """The costmap and planners of ``grid`` (any thread; nothing here changes)."""
        navigator = self.navigator
        return Navigator.prepare_map(grid, navigator.params if navigator is not None else self.params)

    def use_map(self, grid: OccupancyMap, prepared: object | None) -> None:
        """The navigator plans on the active map; a robot that starts without one gets it with the first map."""
        nav_map = prepared if isinstance(prepared, NavMap) else None
        if self.navigator is None:
            self.navigator = Navigator(grid, self.params, prepared=nav_map)
        else:
            self.navigator.set_map(grid, nav_map)

    @property
    def goal(self) -> Pose2D | None:
        return None if self.navigator is None else self.navigator.goal
