"""The dashboard's changes to the active map's named places, checked before anything is stored.

The gateway hands every place request here (`PlaceEditor`): a name that is not a usable place name, a pose
outside the active map or in a wall, a new name another place already has, or a map being built are refused
with the reason, and nothing changes; an accepted change is stored with the map at once
(`atemr.robot.mapping.MapService.set_places`), so it survives a restart and travels with the map's export.
"""

from __future__ import annotations

import math

from atemr.domain.places import PLACE_KINDS, Place, PlaceKind, Places
from atemr.errors import ConfigError, brief
from atemr.msgs import Pose2D
from atemr.robot.mapping import MapService
from atemr.ui.gateway import CommandResult


class PlaceEditor:
    """Add, move, rename and delete the active map's places (see the module docstring)."""

    def __init__(self, maps: MapService) -> None:
        self.maps = maps

    def find(self, name: str) -> Place | str:
        """The active map's place ``name``, or why there is none (with the closest names)."""
        if self.maps.active is None:
            return "no active map: select a map first"
        try:
            return self.maps.places.find(name)
        except ConfigError as exc:
            return exc.reason

    def _where_problem(self, pose: Pose2D) -> str | None:
        grid = self.maps.active
        if grid is None:
            return "no active map: select a map first"
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad)):
            return f"a place needs a finite pose, got {brief(pose)}"
        row, col = grid.world_to_cell(pose.x_m, pose.y_m)
        if not grid.contains(row, col):
            return f"({pose.x_m:.2f}, {pose.y_m:.2f}) is outside the map {self.maps.active_name}"
        if grid.occupied[int(row), int(col)]:
            return f"({pose.x_m:.2f}, {pose.y_m:.2f}) is in an obstacle on the map"
        return None

    def save(self, name: str, pose: Pose2D, kind: str = "place", previous: str | None = None) -> CommandResult:
        """Add ``name`` at ``pose``, or move and/or rename ``previous`` to it."""
        why = self._where_problem(pose)
        if why is not None:
            return CommandResult.refused(why)
        if kind not in PLACE_KINDS:
            return CommandResult.refused(f"a place's kind is one of {', '.join(PLACE_KINDS)}, got {brief(kind)}")
        places = self.maps.places
        try:
            place = Place(name.strip() if isinstance(name, str) else name, pose, _kind(kind))
            if previous is None:
                changed = places.with_place(place)
            else:
                changed = places.renamed(previous, place.name)
                changed = changed.with_place(place, replace=True)
            return self._store(changed)
        except ConfigError as exc:
            return CommandResult.refused(exc.reason)

    def delete(self, name: str) -> CommandResult:
        if self.maps.active is None:
            return CommandResult.refused("no active map: select a map first")
        try:
            return self._store(self.maps.places.without(name))
        except ConfigError as exc:
            return CommandResult.refused(exc.reason)

    def _store(self, places: Places) -> CommandResult:
        try:
            self.maps.set_places(places)
        except ConfigError as exc:
            return CommandResult.refused(exc.reason)
        except OSError as exc:
            return CommandResult.refused(f"places not saved: {exc.strerror}")
        return CommandResult.accepted()


def _kind(kind: str) -> PlaceKind:
    return "dock" if kind == "dock" else "place"
