"""Socket.IO events of the Mapping page: begin/end a mapping session, save or discard, select a map; and the
active map's named places (add, move, rename, delete), which the Control page edits too."""

from __future__ import annotations

import re
from typing import Any

from atemr.domain.places import MAX_NAME_CHARS
from atemr.errors import ProtocolError
from atemr.ui import payload
from atemr.ui.gateway import CommandResult, RobotGateway
from atemr.ui.sockets import EventGroup

MAP_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")

events = EventGroup("mapping")


def map_name(event: str, data: Any) -> str:
    """A map name usable as a file stem: letters, digits, ``_``, ``.``, ``-`` (not leading), 1-64."""
    name = payload.text(event, data, "name", max_len=64)
    if name.endswith((".yaml", ".yml")):
        name = name.rsplit(".", 1)[0]
    if not MAP_NAME_RE.match(name) or ".." in name:
        raise ProtocolError(f"{event}.name: a map name is 1-64 letters, digits, '_', '.', '-', got {name!r}")
    return name


@events.on("mapping_begin")
def mapping_begin(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.begin_mapping()


@events.on("mapping_end")
def mapping_end(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.end_mapping()


@events.on("map_save")
def map_save(robot: RobotGateway, data: Any) -> CommandResult:
    """``{name}``: store the map just built; it becomes the active map."""
    return robot.save_map(map_name("map_save", data))


@events.on("map_discard")
def map_discard(robot: RobotGateway, data: Any) -> CommandResult:
    return robot.discard_map()


@events.on("map_select")
def map_select(robot: RobotGateway, data: Any) -> CommandResult:
    """``{name}``: switch the active map."""
    return robot.select_map(map_name("map_select", data))


@events.on("place_save")
def place_save(robot: RobotGateway, data: Any) -> CommandResult:
    """``{name, x_m, y_m, yaw_rad, kind?, previous?}``: add a place, or move and/or rename ``previous``."""
    name = payload.text("place_save", data, "name", max_len=MAX_NAME_CHARS)
    pose = payload.pose("place_save", data)
    fields = payload.mapping("place_save", data)
    kind = payload.text("place_save", data, "kind", max_len=8) if "kind" in fields else "place"
    previous = payload.text("place_save", data, "previous", max_len=MAX_NAME_CHARS) \
        if fields.get("previous") is not None else None
    return robot.save_place(name, pose, kind, previous)


@events.on("place_delete")
def place_delete(robot: RobotGateway, data: Any) -> CommandResult:
    """``{name}``."""
    return robot.delete_place(payload.text("place_delete", data, "name", max_len=MAX_NAME_CHARS))
