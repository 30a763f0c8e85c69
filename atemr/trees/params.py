"""Parameter types shared by leaves and missions."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from atemr.msgs import Pose2D


@dataclass(frozen=True)
class PoseParams:
    """A goal pose in the map frame: the parameters of ``GoToPose`` and of every pose in a mission."""

    x_m: float = field(default=0.0, metadata={"required": True, "min": -1e4, "max": 1e4})
    y_m: float = field(default=0.0, metadata={"required": True, "min": -1e4, "max": 1e4})
    yaw_rad: float = field(default=0.0, metadata={"min": -2 * math.pi, "max": 2 * math.pi})

    def pose(self) -> Pose2D:
        return Pose2D(self.x_m, self.y_m, self.yaw_rad)
