"""Navigation on the robot: the agent's `NavigatorPort` over one `Navigator`, kept on the active map.

`atemr.trees.navigator_port.NavigatorPort` adapts a `Navigator` to the agent's `NavigationPort`; this
module gives it its inputs on the robot (the localized map pose, the latest scan, the localization flag,
the measured twist) and rebuilds the navigator's costmap whenever the map service switches maps.
"""

from __future__ import annotations

from collections.abc import Callable

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
        if maps.active is None:
            raise ValueError("navigation needs an active map (the map store always offers the built-in one)")
        super().__init__(Navigator(maps.active, params), pose=localization.map_pose, scan=scan,
                         localized=lambda: localization.localized, velocity=velocity)
        maps.on_map_change(self.navigator.set_map)

    @property
    def goal(self) -> Pose2D | None:
        return self.navigator.goal
