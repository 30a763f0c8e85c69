"""The ``nav`` configuration section: what an operator or integrator tunes about navigation, validated by
`atemr.typed` (like `atemr.skills.localization.config.LocalizationConfig`, it lives beside the code it configures).

`nav_params` turns it into the navigator's `NavParams`, together with the motion pipeline's stop zone
(``motion.stop_distance_m``, ``motion.brake_latency_s``): the local planner keeps its plans inside what the
pipeline will drive, so both must agree, and the one place they are set is ``motion``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

from atemr.errors import ConfigError, NavigationError
from atemr.skills.ramp import MotionLimits

if TYPE_CHECKING:  # the planners import scipy.ndimage (most of a second): only what builds them pays for it
    from atemr.skills.nav.navigator import NavParams


@dataclass(frozen=True)
class NavConfig:
    """Goal tolerances, footprint and margins, speeds, and how long to wait (names as in ROS move_base where
    there is one)."""

    xy_tolerance_m: float = field(default=0.25, metadata={"min": 0.05, "max": 2.0, "help": "goal position tolerance"})
    yaw_tolerance_rad: float = field(default=0.13, metadata={"min": 0.02, "max": 3.1416,
                                                             "help": "goal heading tolerance"})
    robot_radius_m: float = field(default=0.25, metadata={"min": 0.05, "max": 2.0, "help": "round footprint"})
    footprint_padding_m: float = field(default=0.05, metadata={"min": 0.0, "max": 0.5,
                                                               "help": "added to the radius: the inscribed zone"})
    obstacle_padding_m: float = field(default=0.1, metadata={"min": 0.0, "max": 1.0,
                                                             "help": "extra room from what is not in the map"})
    inflation_radius_m: float = field(default=0.8, metadata={"min": 0.1, "max": 5.0, "help": "cost decays to here"})
    max_linear_mps: float = field(default=0.5, metadata={"min": 0.05, "max": 1.6, "help": "planned top speed"})
    max_angular_radps: float = field(default=1.2, metadata={"min": 0.1, "max": 6.0, "help": "planned turn rate"})
    obstacle_wait_s: float = field(default=60.0, metadata={"min": 1.0, "max": 3600.0,
                                                           "help": "wait for a blocked way after the recoveries"})
    timeout_s: float = field(default=600.0, metadata={"min": 1.0, "max": 86_400.0, "help": "per goal"})
    depth_layer: bool = field(default=True, metadata={
        "help": "fold the depth camera's frames into a voxel obstacle layer (what is between the floor and the "
                "robot's height: table tops, shelves, things under the lidar) for the costmap and the stop zone"})
    planner: str = field(default="astar", metadata={"choices": ("astar", "dijkstra"),
                                                    "help": "global planner: the same paths, A* searches less"})

    def nav_params(self, motion: MotionLimits | None = None) -> NavParams:
        """The navigator's parameters, with the stop zone of ``motion`` (raises `ConfigError` on inconsistent
        values, naming the ``nav`` key)."""
        from atemr.skills.nav.costmap import CostmapParams
        from atemr.skills.nav.global_planner import Algorithm
        from atemr.skills.nav.local_planner import LocalPlannerParams
        from atemr.skills.nav.navigator import NavParams

        m = motion or MotionLimits()
        try:
            base = NavParams()
            return dataclasses.replace(
                base,
                costmap=dataclasses.replace(CostmapParams(), robot_radius_m=self.robot_radius_m,
                                            footprint_padding_m=self.footprint_padding_m,
                                            obstacle_padding_m=self.obstacle_padding_m,
                                            inflation_radius_m=self.inflation_radius_m),
                local=dataclasses.replace(LocalPlannerParams(), max_linear_mps=self.max_linear_mps,
                                          max_angular_radps=self.max_angular_radps,
                                          stop_distance_m=m.stop_distance_m, brake_latency_s=m.brake_latency_s),
                planner=dataclasses.replace(base.planner, algorithm=cast(Algorithm, self.planner)),
                xy_tolerance_m=self.xy_tolerance_m, yaw_tolerance_rad=self.yaw_tolerance_rad,
                arrive_m=min(base.arrive_m, self.xy_tolerance_m),
                obstacle_wait_s=self.obstacle_wait_s, timeout_s=self.timeout_s,
            )
        except NavigationError as exc:
            raise ConfigError(str(exc), path="nav") from None


__all__ = ["NavConfig"]
