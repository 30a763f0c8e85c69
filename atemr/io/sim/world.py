"""A simulated world: a map_server map plus what a map cannot hold.

A world file (YAML) names its map and adds furniture the lidar and the camera see (with a height and a
colour for the camera), drop zones the cliff sensors must notice (stairs, a balcony edge), moving
obstacles (a person walking a path, a pet wandering an area) and the robot's start pose::

    name: studio
    map: studio.yaml                     # relative to this file
    start: [2.9, 2.6, 0.0]               # x_m, y_m, yaw_rad
    furniture:
      - {name: sofa, box: [0.2, 1.0, 1.1, 3.0], height_m: 0.8, color: [90, 110, 160], mapped: true}
      - {name: basket, circle: [3.6, 1.2, 0.25], height_m: 0.5, color: [200, 170, 90]}
      - {name: shelf, box: [2.0, 0.0, 2.8, 0.3], clearance_m: 0.9, height_m: 0.95}   # floats: free below 0.9 m
    drop_zones:
      - {name: balcony edge, box: [3.2, -1.6, 5.3, -1.2], depth_m: 2.5}
      - {name: stairs, polygon: [[0, 0], [1, 0], [1, 1]], depth_m: 0.18}
    moving:
      - {name: carer, kind: person, path: [[0.9, 4.2], [4.8, 4.2]], speed_mps: 0.6}
      - {name: cat, kind: pet, area: [5.8, 2.8, 8.7, 4.3], speed_mps: 0.4}

An object spans the heights from ``clearance_m`` (the free space under it, 0 by default: standing on the
floor) to ``height_m``: a table top from 0.70 to 0.75 m (its legs are objects of their own), a wall shelf, a
drawer left open. The lidar sees only what crosses its scan plane; the depth camera and the robot's volume
(`atemr.skills.body`) meet everything.

``mapped: true`` furniture is also drawn into the map by the world's generator script (as a SLAM map
would show it); the simulator treats all furniture alike. A plain map YAML is also a world: no extras,
start pose at the free spot nearest the map's (0, 0) with room for the robot.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError
from atemr.io.sim.maps import is_map_document, load_map, read_yaml
from atemr.msgs import Pose2D
from atemr.yamlsafe import key_mark_of, mark_of

Color = tuple[int, int, int]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Furniture:
    """A static obstacle: an axis-aligned box ``[x0, y0, x1, y1]`` or a circle ``[x, y, r]``, spanning the
    heights ``clearance_m`` (free space under it) to ``height_m``."""

    name: str
    shape: Literal["box", "circle"]
    params: tuple[float, ...]
    height_m: float = 0.8
    color: Color = (150, 120, 90)
    mapped: bool = False
    clearance_m: float = 0.0

    def spans(self, bottom_m: float, top_m: float) -> bool:
        """Whether the object is somewhere between the heights ``bottom_m`` and ``top_m`` (a plane when equal)."""
        return self.clearance_m <= top_m and self.height_m >= bottom_m

    def contains(self, x: FloatArray, y: FloatArray) -> NDArray[np.bool_]:
        """Which points lie inside (used to rasterise it on the grid)."""
        if self.shape == "box":
            x0, y0, x1, y1 = self.params
            return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
        cx, cy, r = self.params
        return (x - cx) ** 2 + (y - cy) ** 2 <= r * r


@dataclass(frozen=True)
class DropZone:
    """Floor that falls away (``depth_m`` below the floor) inside a polygon: stairs, a balcony edge."""

    name: str
    polygon: tuple[tuple[float, float], ...]
    depth_m: float = 1.0

    def contains(self, x: FloatArray, y: FloatArray) -> NDArray[np.bool_]:
        """Point-in-polygon (even-odd rule), vectorised over points and edges."""
        px = np.asarray(x, dtype=np.float64)[..., None]
        py = np.asarray(y, dtype=np.float64)[..., None]
        poly = np.asarray(self.polygon, dtype=np.float64)
        x1, y1 = poly[:, 0], poly[:, 1]
        x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
        straddles = (y1 > py) != (y2 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = x1 + (py - y1) * (x2 - x1) / (y2 - y1)
        inside: NDArray[np.bool_] = (np.count_nonzero(straddles & (px < x_cross), axis=-1) % 2) == 1
        return inside


@dataclass(frozen=True)
class MoverSpec:
    """A moving obstacle: a person walking ``path`` (looping back to the start, or back and forth), or a
    pet wandering at random inside ``area`` ``[x0, y0, x1, y1]``. Seen as a vertical cylinder."""

    name: str
    kind: Literal["person", "pet"]
    radius_m: float
    height_m: float
    speed_mps: float
    color: Color
    path: tuple[tuple[float, float], ...] = ()
    loop: bool = False
    area: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class World:
    """Everything the simulator needs about the place: map, extras and start pose."""

    name: str
    map: OccupancyMap
    start: Pose2D
    furniture: tuple[Furniture, ...] = ()
    drop_zones: tuple[DropZone, ...] = ()
    movers: tuple[MoverSpec, ...] = ()
    source: Path | None = None
    wall_height_m: float = 2.5


# -- loading ---------------------------------------------------------------------------------
_WORLD_KEYS = ("name", "map", "start", "furniture", "drop_zones", "moving", "wall_height_m")
_FURNITURE_KEYS = ("name", "box", "circle", "height_m", "clearance_m", "color", "mapped")
_DROP_KEYS = ("name", "box", "polygon", "depth_m")
_MOVER_KEYS = ("name", "kind", "radius_m", "height_m", "speed_mps", "color", "path", "loop", "area")
_MOVER_DEFAULTS: dict[str, dict[str, Any]] = {
    "person": {"radius_m": 0.22, "height_m": 1.7, "speed_mps": 0.7, "color": (200, 80, 60)},
    "pet": {"radius_m": 0.15, "height_m": 0.35, "speed_mps": 0.4, "color": (230, 150, 40)},
}


class _Doc:
    """Helpers that raise `ConfigError` at the exact place in a world file."""

    def __init__(self, file: str) -> None:
        self.file = file

    def error(self, message: str, container: Any, key: Any, path: str, *, on_key: bool = False) -> ConfigError:
        line, col = key_mark_of(container, key) if on_key else mark_of(container, key)
        return ConfigError(message, file=self.file, line=line, column=col, path=path)

    def mapping(self, value: Any, container: Any, key: Any, path: str, known: Sequence[str]) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(f"expected a mapping, got {value!r}", container, key, path)
        for k in value:
            if k not in known:
                close = difflib.get_close_matches(str(k), list(known), n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                where = f"{path}.{k}" if path else str(k)
                raise self.error(f"unknown key '{k}'{hint}; known keys: {', '.join(known)}", value, k, where,
                                 on_key=True)
        return value

    def numbers(self, container: Any, key: Any, path: str, count: int | None = None) -> tuple[float, ...]:
        value = container[key]
        ok = isinstance(value, list) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
        )
        if not ok or (count is not None and len(value) != count):
            what = f"{count} numbers" if count is not None else "a list of numbers"
            raise self.error(f"expected {what}, got {value!r}", container, key, path)
        return tuple(float(v) for v in value)

    def number(self, container: Any, key: str, path: str, default: float, *, positive: bool = True) -> float:
        if key not in container:
            return default
        value = container[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(f"expected a number, got {value!r}", container, key, path)
        if positive and value <= 0:
            raise self.error(f"must be > 0, got {value!r}", container, key, path)
        return float(value)

    def points(self, container: Any, key: str, path: str, minimum: int) -> tuple[tuple[float, float], ...]:
        value = container[key]
        if not isinstance(value, list) or len(value) < minimum:
            raise self.error(f"expected a list of at least {minimum} [x, y] points, got {value!r}",
                             container, key, path)
        pairs = [self.numbers(value, i, f"{path}[{i}]", 2) for i in range(len(value))]
        return tuple((p[0], p[1]) for p in pairs)

    def color(self, container: Any, key: str, path: str, default: Color) -> Color:
        if key not in container:
            return default
        rgb = self.numbers(container, key, path, 3)
        if not all(0 <= c <= 255 for c in rgb):
            raise self.error(f"colour components must be within 0..255, got {container[key]!r}", container, key, path)
        return int(rgb[0]), int(rgb[1]), int(rgb[2])

    def name(self, container: Any, path: str, default: str) -> str:
        value = container.get("name", default)
        if not isinstance(value, str) or not value:
            raise self.error(f"expected a non-empty string, got {value!r}", container, "name", path)
        return value

    def box(self, container: Any, key: str, path: str) -> tuple[float, float, float, float]:
        x0, y0, x1, y1 = self.numbers(container, key, path, 4)
        if x1 <= x0 or y1 <= y0:
            raise self.error(f"expected [x0, y0, x1, y1] with x1 > x0 and y1 > y0, got {container[key]!r}",
                             container, key, path)
        return x0, y0, x1, y1


def shipped_world_path(name: str) -> Path | None:
    """The world file of a world shipped with the package (``atemr/worlds/<name>/world.yaml``), if any."""
    base = Path(__file__).resolve().parents[2] / "worlds"
    candidate = base / name / "world.yaml"
    return candidate if candidate.is_file() else None


def shipped_world_names() -> list[str]:
    """The names of the worlds shipped with the package."""
    base = Path(__file__).resolve().parents[2] / "worlds"
    return sorted(p.parent.name for p in base.glob("*/world.yaml"))


def load_world(name_or_path: str | Path, *, robot_radius_m: float = 0.25) -> World:
    """Load a shipped world by name (``studio``), a world file, or a bare map_server YAML."""
    text = str(name_or_path)
    path = Path(name_or_path)
    if not path.suffix and not path.exists():
        shipped = shipped_world_path(text)
        if shipped is None:
            known = shipped_world_names()
            close = difflib.get_close_matches(text, known, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise ConfigError(f"unknown world '{text}'{hint}; shipped worlds: {', '.join(known) or 'none'}; "
                              "or give a path to a world or map YAML", path="sim.world")
        path = shipped
    doc = read_yaml(path)
    if is_map_document(doc):
        occupancy = load_map(path)
        return World(occupancy.name, occupancy, default_start(occupancy, robot_radius_m), source=path)
    return _parse_world(doc, path)


def _parse_world(doc: Any, path: Path) -> World:  # noqa: PLR0912, PLR0915  one block per section of the world file, in file order
    file = str(path)
    d = _Doc(file)
    if not isinstance(doc, dict):
        raise ConfigError(f"expected a world mapping with a 'map' key, got {type(doc).__name__}", file=file)
    d.mapping(doc, doc, None, "", _WORLD_KEYS)
    if "map" not in doc:
        raise ConfigError("missing required key 'map' (the map_server YAML of this world)", file=file)
    map_ref = doc["map"]
    if not isinstance(map_ref, str) or not map_ref:
        raise d.error(f"expected a path to a map YAML, got {map_ref!r}", doc, "map", "map")
    map_path = Path(map_ref) if Path(map_ref).is_absolute() else path.parent / map_ref
    if not map_path.is_file():
        raise d.error(f"map file not found: {map_path}", doc, "map", "map")
    occupancy = load_map(map_path)
    name = d.name(doc, "name", path.parent.name if path.name == "world.yaml" else path.stem)
    wall_height = d.number(doc, "wall_height_m", "wall_height_m", 2.5)

    furniture: list[Furniture] = []
    items = doc.get("furniture", [])
    if not isinstance(items, list):
        raise d.error(f"expected a list, got {items!r}", doc, "furniture", "furniture")
    for i, item in enumerate(items):
        p = f"furniture[{i}]"
        d.mapping(item, items, i, p, _FURNITURE_KEYS)
        shapes = [k for k in ("box", "circle") if k in item]
        if len(shapes) != 1:
            raise d.error("give exactly one of 'box: [x0, y0, x1, y1]' or 'circle: [x, y, r]'", items, i, p)
        if shapes[0] == "box":
            params: tuple[float, ...] = d.box(item, "box", f"{p}.box")
        else:
            params = d.numbers(item, "circle", f"{p}.circle", 3)
            if params[2] <= 0:
                raise d.error(f"radius must be > 0, got {params[2]}", item, "circle", f"{p}.circle")
        if not _overlaps_map(occupancy, shapes[0], params):
            raise d.error(f"'{item.get('name', i)}' lies outside the map", item, shapes[0], f"{p}.{shapes[0]}")
        mapped = item.get("mapped", False)
        if not isinstance(mapped, bool):
            raise d.error(f"expected true or false, got {mapped!r}", item, "mapped", f"{p}.mapped")
        height = d.number(item, "height_m", f"{p}.height_m", 0.8)
        clearance = d.number(item, "clearance_m", f"{p}.clearance_m", 0.0, positive=False)
        if not 0 <= clearance < height:
            raise d.error(f"clearance_m must be within [0, height_m), got {clearance!r} (height_m {height!r})",
                          item, "clearance_m", f"{p}.clearance_m")
        furniture.append(Furniture(
            d.name(item, p, f"furniture{i}"), shapes[0], params,  # type: ignore[arg-type]
            height, d.color(item, "color", f"{p}.color", (150, 120, 90)), mapped, clearance,
        ))

    zones: list[DropZone] = []
    items = doc.get("drop_zones", [])
    if not isinstance(items, list):
        raise d.error(f"expected a list, got {items!r}", doc, "drop_zones", "drop_zones")
    for i, item in enumerate(items):
        p = f"drop_zones[{i}]"
        d.mapping(item, items, i, p, _DROP_KEYS)
        if ("box" in item) == ("polygon" in item):
            raise d.error("give exactly one of 'box: [x0, y0, x1, y1]' or 'polygon: [[x, y], ...]'", items, i, p)
        if "box" in item:
            x0, y0, x1, y1 = d.box(item, "box", f"{p}.box")
            polygon: tuple[tuple[float, float], ...] = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
        else:
            polygon = d.points(item, "polygon", f"{p}.polygon", 3)
        zones.append(DropZone(d.name(item, p, f"drop{i}"), polygon, d.number(item, "depth_m", f"{p}.depth_m", 1.0)))

    movers: list[MoverSpec] = []
    items = doc.get("moving", [])
    if not isinstance(items, list):
        raise d.error(f"expected a list, got {items!r}", doc, "moving", "moving")
    for i, item in enumerate(items):
        p = f"moving[{i}]"
        d.mapping(item, items, i, p, _MOVER_KEYS)
        kind = item.get("kind")
        if kind not in _MOVER_DEFAULTS:
            raise d.error(f"expected kind 'person' or 'pet', got {kind!r}", item if "kind" in item else items,
                          "kind" if "kind" in item else i, f"{p}.kind")
        defaults = _MOVER_DEFAULTS[kind]
        path_pts: tuple[tuple[float, float], ...] = ()
        area = None
        if kind == "person":
            if "path" not in item:
                raise d.error("a person needs a 'path' of at least two [x, y] points", items, i, p)
            path_pts = d.points(item, "path", f"{p}.path", 2)
        else:
            if "area" not in item:
                raise d.error("a pet needs an 'area' [x0, y0, x1, y1] to wander in", items, i, p)
            area = d.box(item, "area", f"{p}.area")
        loop = item.get("loop", False)
        if not isinstance(loop, bool):
            raise d.error(f"expected true or false, got {loop!r}", item, "loop", f"{p}.loop")
        movers.append(MoverSpec(
            d.name(item, p, f"{kind}{i}"), kind,
            d.number(item, "radius_m", f"{p}.radius_m", defaults["radius_m"]),
            d.number(item, "height_m", f"{p}.height_m", defaults["height_m"]),
            d.number(item, "speed_mps", f"{p}.speed_mps", defaults["speed_mps"]),
            d.color(item, "color", f"{p}.color", defaults["color"]),
            path_pts, loop, area,
        ))

    if "start" in doc:
        sx, sy, syaw = d.numbers(doc, "start", "start", 3)
        start = Pose2D(sx, sy, syaw)
        row, col = occupancy.world_to_cell(sx, sy)
        if not occupancy.contains(row, col):
            raise d.error(f"start ({sx}, {sy}) is outside the map", doc, "start", "start")
    else:
        start = default_start(occupancy, 0.25)
    return World(name, occupancy, start, tuple(furniture), tuple(zones), tuple(movers), path, wall_height)


def _overlaps_map(occupancy: OccupancyMap, shape: str, params: tuple[float, ...]) -> bool:
    """Whether a box ``[x0, y0, x1, y1]`` or circle ``[x, y, r]`` touches the map's area (its bounding box)."""
    x0, y0, x1, y1 = params if shape == "box" else (params[0] - params[2], params[1] - params[2],
                                                     params[0] + params[2], params[1] + params[2])
    corners_x, corners_y = occupancy.cell_to_world(
        np.array([0, 0, occupancy.height - 1, occupancy.height - 1]), np.array([0, occupancy.width - 1] * 2)
    )
    half = occupancy.resolution_m  # cell centres → cell edges, generously (covers a rotated origin too)
    return bool(x1 >= corners_x.min() - half and x0 <= corners_x.max() + half
                and y1 >= corners_y.min() - half and y0 <= corners_y.max() + half)


def default_start(occupancy: OccupancyMap, robot_radius_m: float) -> Pose2D:
    """The free cell nearest the map frame's (0, 0) with room for the robot (or the most open cell)."""
    # Beyond the map's edge counts as blocked too (padding), so the robot does not start half off the map.
    open_cells = np.pad(~occupancy.occupied & ~occupancy.unknown, 1)
    clearance = ndimage.distance_transform_edt(open_cells)[1:-1, 1:-1] * occupancy.resolution_m
    roomy = (clearance > robot_radius_m + occupancy.resolution_m) & occupancy.free
    if not roomy.any():
        row, col = np.unravel_index(int(np.argmax(clearance)), clearance.shape)
    else:
        rows, cols = np.nonzero(roomy)
        x, y = occupancy.cell_to_world(rows, cols)
        best = int(np.argmin(x * x + y * y))
        row, col = rows[best], cols[best]
    x, y = occupancy.cell_to_world(row, col)
    return Pose2D(float(x), float(y), 0.0)
