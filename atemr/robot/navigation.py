"""Navigation on the robot: the agent's `NavigatorPort` over one `Navigator`, kept on the active map.

`atemr.trees.navigator_port.NavigatorPort` adapts a `Navigator` to the agent's `NavigationPort`; this
module gives it its inputs on the robot (the localized map pose, the latest scan, the localization flag,
the measured twist) and rebuilds the navigator's costmap whenever the map service switches maps.
"""

from __future__ import annotations

from collections.abc import Callable

from atemr.io.sim.maps import OccupancyMap
from atemr.msgs import LaserScan, Pose2D, Twist
from atemr.robot.mapping import MapService
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.nav.navigator import Navigator, NavParams
from atemr.trees.navigator_port import NavigatorPort


class RobotNavigation(NavigatorPort):
    """The robot's `NavigationPort`; ``last_status`` and ``goal`` feed the dashboard's paths and goal marker."""

    def __init__(self, maps: MapService, localization: LocalizationPipeline,
                 scan: Callable[[], LaserScan | None], velocity: Callable[[], Twist | None],
                 params: NavParams | None = None) -> None:
        super().__init__(None, pose=localization.map_pose, scan=scan, localized=lambda: localization.localized,
                         velocity=velocity)
        self.params = params
        if maps.active is not None:
            self._use_map(maps.active)
        maps.on_map_change(self._use_map)

    def _use_map(self, grid: OccupancyMap) -> None:
        """The navigator plans on the active map; a robot that starts without one gets it with the first map."""
        if self.navigator is None:
            self.navigator = Navigator(grid, self.params)
        else:
            self.navigator.set_map(grid)

    @property
    def goal(self) -> Pose2D | None:
        return None if self.navigator is None else self.navigator.goal
