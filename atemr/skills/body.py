"""The robot's whole volume: the base footprint and the height profile above it (the ``body`` section).

KAY is not a disc on the floor: its tablet sits on a mast about a metre up. A 2-D footprint is enough for
what the lidar sees, but a dining-table top at 0.72 m passes over the lidar plane and meets the mast. So the
configuration describes the volume as a stack of vertical cylinders about the base's axis (KAY is round
about its axle, so a part's plan shape does not turn with the heading): the base (the footprint, from the
floor to ``base_height_m``), the mast, and the tablet at its height and size. Everything the robot carries
stays inside the footprint in plan view, so the planners and the costmap keep the round footprint and use
the profile for *which heights* are obstacles (between a floor margin and `RobotBody.height_m`); the
simulator checks collisions part by part, so a table top hits the mast while the base passes under it.

Pure data, no I/O: the simulator, the depth obstacle layer and the safety zones all read one `RobotBody`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from atemr.errors import ConfigError


@dataclass(frozen=True)
class BodyPart:
    """One vertical cylinder of the robot: ``radius_m`` about the base's axis, from ``bottom_m`` to ``top_m``."""

    name: str
    radius_m: float
    bottom_m: float
    top_m: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise ConfigError(f"{self.name}: radius must be > 0, got {self.radius_m!r}", path="body")
        if not (math.isfinite(self.bottom_m) and math.isfinite(self.top_m) and 0 <= self.bottom_m < self.top_m):
            raise ConfigError(f"{self.name}: need 0 <= bottom < top, got {self.bottom_m!r}..{self.top_m!r}",
                              path="body")

    def overlaps(self, bottom_m: float, top_m: float) -> bool:
        """Whether something spanning heights ``bottom_m``..``top_m`` is at this part's height."""
        return bottom_m < self.top_m and top_m > self.bottom_m


@dataclass(frozen=True)
class RobotBody:
    """The robot's volume as parts, the base first (its radius is the footprint)."""

    parts: tuple[BodyPart, ...]

    def __post_init__(self) -> None:
        if not self.parts:
            raise ConfigError("the robot needs at least its base", path="body")
        if any(p.radius_m > self.footprint_radius_m + 1e-9 for p in self.parts):
            raise ConfigError("every part must stay inside the base's footprint in plan view", path="body")

    @property
    def footprint_radius_m(self) -> float:
        return self.parts[0].radius_m

    @property
    def height_m(self) -> float:
        """The top of the robot: nothing above it can touch it."""
        return max(p.top_m for p in self.parts)

    def parts_between(self, bottom_m: float, top_m: float) -> tuple[BodyPart, ...]:
        """The parts at the height of something spanning ``bottom_m``..``top_m``."""
        return tuple(p for p in self.parts if p.overlaps(bottom_m, top_m))


@dataclass(frozen=True)
class BodyConfig:
    """KAY's height profile above the base footprint (``nav.robot_radius_m``); metres from the floor."""

    base_height_m: float = field(default=0.30, metadata={"min": 0.05, "max": 1.0,
                                                         "help": "top of the base (the lidar scans inside it)"})
    mast_radius_m: float = field(default=0.04, metadata={"min": 0.01, "max": 0.5, "help": "the mast's radius"})
    mast_height_m: float = field(default=1.0, metadata={"min": 0.1, "max": 2.5, "help": "top of the mast"})
    tablet_height_m: float = field(default=1.05, metadata={"min": 0.1, "max": 2.5,
                                                           "help": "the tablet's centre, above the floor"})
    tablet_width_m: float = field(default=0.26, metadata={"min": 0.02, "max": 1.0, "help": "the tablet's width"})
    tablet_tall_m: float = field(default=0.18, metadata={"min": 0.02, "max": 1.0,
                                                         "help": "the tablet's height (portrait side)"})

    def body(self, footprint_radius_m: float = 0.25) -> RobotBody:
        """The volume as parts: base (the footprint), mast, tablet (a cylinder as wide as the tablet)."""
        half = self.tablet_tall_m / 2
        return RobotBody((
            BodyPart("base", footprint_radius_m, 0.0, self.base_height_m),
            BodyPart("mast", self.mast_radius_m, self.base_height_m, max(self.mast_height_m,
                                                                          self.base_height_m + 0.01)),
            BodyPart("tablet", self.tablet_width_m / 2, max(self.tablet_height_m - half, 0.0),
                     self.tablet_height_m + half),
        ))


#: KAY with the default profile and the thesis's 0.25 m footprint.
KAY = BodyConfig().body()

__all__ = ["KAY", "BodyConfig", "BodyPart", "RobotBody"]
