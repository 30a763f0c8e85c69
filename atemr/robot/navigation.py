"""Navigation on the robot: the agent's `NavigatorPort` over one `Navigator`, kept on the active map.

`atemr.robot.navigator_port.NavigatorPort` adapts a `Navigator` to the agent's `NavigationPort`; this
module gives it its inputs on the robot (the localized map pose, the latest scan, the localization flag,
the measured twist) and gives the navigator each new map's costmap, prepared off the robot's thread when
the map service switches maps (`atemr.robot.mapping.MapUser`).

With a depth camera it also runs the depth obstacle layer (`atemr.skills.nav.voxel_layer`) on the navigator's
costmap: every frame is folded in at the localized pose, and the layer's nearest obstacles round the robot go
to the motion pipeline's slow and stop zones (``on_clearance``), whether the robot navigates or is driven.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from atemr.domain.maps import OccupancyMap
from atemr.io.devices.base import Device
from atemr.msgs import DepthImage, LaserScan, Pose2D, Twist
from atemr.robot.mapping import MapService
from atemr.robot.navigator_port import NavigatorPort
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.motion_pipeline import TimedClearance
from atemr.skills.nav.navigator import Navigator, NavMap, NavParams
from atemr.skills.nav.voxel_layer import VoxelLayer, VoxelLayerParams, load_compiled


class RobotNavigation(NavigatorPort):
    """The robot's `NavigationPort`; ``last_status`` and ``goal`` feed the dashboard's paths and goal marker."""

    def __init__(self, maps: MapService, localization: LocalizationPipeline,
                 scan: Callable[[], LaserScan | None], velocity: Callable[[], Twist | None],
                 params: NavParams | None = None, *, depth: Device[DepthImage] | None = None,
                 depth_layer: VoxelLayerParams | None = None,
                 on_clearance: Callable[[TimedClearance], None] | None = None) -> None:
        super().__init__(None, pose=localization.map_pose, scan=scan, localized=lambda: localization.localized,
                         velocity=velocity, places=lambda: maps.places)
        self.params = params
        self._map_pose = localization.map_pose
        #: The depth obstacle layer's settings (None: the layer is off), the layer on the current costmap.
        self.depth_layer = depth_layer
        self.voxels: VoxelLayer | None = None
        self._on_clearance = on_clearance
        if maps.active is not None:
            self.use_map(maps.active, None)
        maps.add_map_user(self)
        if depth is not None and depth_layer is not None:
            depth.subscribe(self.on_depth)
            load_compiled()  # the layer is built at the first frame, on the robot's thread: its loop is ready now

    def on_depth(self, image: DepthImage) -> None:
        """A depth frame into the layer at the localized pose (nothing before a map and a pose)."""
        navigator, pose = self.navigator, self._map_pose()
        if navigator is None or pose is None or self.depth_layer is None:
            return
        layer = self.voxels
        if layer is None or layer.costmap is not navigator.costmap:  # a new map: a new grid
            layer = self.voxels = VoxelLayer(navigator.costmap, self.depth_layer)
        layer.update(image, pose, self._scan())
        if self._on_clearance is not None:
            self._on_clearance(TimedClearance(layer.clearance(pose), image.t))

    def depth_obstacles(self) -> NDArray[np.float64]:
        """What the depth obstacle layer holds now, (N, 2) map-frame cell centres (none without the layer)."""
        layer = self.voxels
        return layer.obstacle_points() if layer is not None else np.zeros((0, 2))

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
