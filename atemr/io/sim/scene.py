"""The simulator's own view of a world: what blocks rays and bodies, cell by cell.

The navigation map says what the robot *knows*; the scene is what is really there: the map's occupied
cells (walls) plus every piece of furniture and every obstacle dropped at run time, rasterised into a
label grid (0 free, 1 wall, 2+ an object) in the map's frame. Lidar, camera and collisions all read it,
so what the robot bumps into is exactly what its sensors could have seen. Moving obstacles are
circles kept outside the grid (see `atemr.io.sim.movers`).

Objects have a vertical extent (``clearance_m`` to ``height_m``). Walls stand from the floor to the wall
height. `Scene.caster_at` gives the grid of what crosses one horizontal plane (the lidar's), and
`Scene.body_clearance` checks the robot's volume part by part against the grid of what is at each part's
heights, so a table top at 0.72 m is missed by the lidar, passed under by the base and hit by the mast.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.errors import ConfigError
from atemr.io.sim.raycast import GridCaster
from atemr.io.sim.world import Color, Furniture, World
from atemr.msgs import Pose2D
from atemr.skills.body import RobotBody

WALL = 1
FIRST_OBJECT = 2
WALL_COLOR: Color = (205, 200, 190)


@dataclass(frozen=True)
class Contact:
    """The closest obstacle to a body: signed clearance (negative: overlapping) and what it is."""

    clearance_m: float
    what: str
    #: Which part of the robot's volume is nearest (`atemr.skills.body`; empty for a plain disc).
    part: str = ""


class Scene:
    """Label grid of static obstacles, with run-time obstacles that can be dropped and removed."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.map = world.map
        self.resolution_m = world.map.resolution_m
        rows, cols = np.indices(world.map.data.shape)
        self._cell_x, self._cell_y = world.map.cell_to_world(rows, cols)
        self._objects: dict[int, Furniture] = {}
        self._next_label = FIRST_OBJECT
        for item in world.furniture:
            self._add(item, check_inside=True)
        depth = np.zeros(world.map.data.shape, dtype=np.float64)
        for zone in world.drop_zones:
            depth = np.where(zone.contains(self._cell_x, self._cell_y), np.maximum(depth, zone.depth_m), depth)
        depth.setflags(write=False)
        #: How far the floor drops in each cell (0: normal floor); the deepest zone wins where zones overlap.
        self.drop_depth_m = depth
        self.drop_mask = depth > 0
        self.drop_mask_padded = np.pad(self.drop_mask, 1)
        #: The world-frame box (x0, y0, x1, y1) that holds every drop cell with a cell to spare, or None: the
        #: camera looks cells up for the floor points inside it only.
        self.drop_bounds_m: tuple[float, float, float, float] | None = None
        if self.drop_mask.any():
            xs, ys, pad = self._cell_x[self.drop_mask], self._cell_y[self.drop_mask], self.resolution_m
            self.drop_bounds_m = (float(xs.min()) - pad, float(ys.min()) - pad, float(xs.max()) + pad,
                                  float(ys.max()) + pad)
        self._rebuild()
        self._footprints: dict[float, tuple[NDArray[np.intp], NDArray[np.intp]]] = {}

    # -- objects -------------------------------------------------------------------------------
    def _add(self, item: Furniture, *, check_inside: bool) -> int:
        label = self._next_label
        if label > np.iinfo(np.int16).max:
            raise ConfigError("too many objects in the scene")
        if check_inside and not item.contains(self._cell_x, self._cell_y).any():
            raise ConfigError(f"furniture '{item.name}' covers no cell of the map", file=self.world.source,
                              path="furniture")
        self._objects[label] = item
        self._next_label += 1
        return label

    def add_object(self, item: Furniture) -> int:
        """Place an obstacle at run time (the dashboard's 'drop obstacle'); returns its id."""
        if not item.contains(self._cell_x, self._cell_y).any():
            raise ConfigError(f"obstacle '{item.name}' is outside the map", path="drop obstacle")
        label = self._add(item, check_inside=False)
        self._rebuild()
        return label

    def remove_object(self, object_id: int) -> Furniture:
        """Take an obstacle away again; unknown ids raise `ConfigError`."""
        try:
            item = self._objects.pop(object_id)
        except KeyError:
            raise ConfigError(f"no obstacle with id {object_id}", path="remove obstacle") from None
        self._rebuild()
        return item

    @property
    def objects(self) -> dict[int, Furniture]:
        """Id → furniture or dropped obstacle currently in the scene."""
        return dict(self._objects)

    def _rebuild(self) -> None:
        #: Replaced whenever furniture is put down or taken away (`view_key`).
        self.revision = object()
        self._masks = {label: item.contains(self._cell_x, self._cell_y) for label, item in self._objects.items()}
        labels = self._labels(None)
        self.labels = labels
        #: Label grids and casters of what lies between two heights or crosses one plane, built when first asked.
        self._layers: dict[tuple[float, float], tuple[NDArray[np.int16], NDArray[np.float64]]] = {}
        self._plane_casters: dict[float, GridCaster] = {}
        self.blocked = labels != 0
        self.walls = labels == WALL
        self.furniture = labels >= FIRST_OBJECT
        #: Ray casters through everything, whatever its height, and for the camera (walls, furniture apart).
        self.blocked_caster = GridCaster(self.blocked, self.resolution_m)
        no_objects = not self.furniture.any()
        self.walls_caster = self.blocked_caster if no_objects else GridCaster(self.walls, self.resolution_m)
        self.furniture_caster = GridCaster(self.furniture, self.resolution_m)
        # Distance from each cell centre to the nearest blocked cell centre: lets `clearance` answer at once
        # when nothing is near, which is almost always.
        self._edt_m = self.blocked_caster.clearance_cells * self.resolution_m
        n = self._next_label
        colors = np.zeros((n, 3), dtype=np.float64)
        heights = np.zeros(n, dtype=np.float64)
        colors[WALL] = WALL_COLOR
        heights[WALL] = self.world.wall_height_m
        for label, item in self._objects.items():
            colors[label] = item.color
            heights[label] = item.height_m
        bottoms = np.zeros(n, dtype=np.float64)
        for label, item in self._objects.items():
            bottoms[label] = item.clearance_m
        self.label_colors = colors
        self.label_heights = heights
        self.label_bottoms = bottoms

    def _labels(self, heights: tuple[float, float] | None) -> NDArray[np.int16]:
        """Walls (the map's occupied cells no object explains) and the objects between ``heights`` (all: None)."""
        labels = np.where(self.map.occupied, WALL, 0).astype(np.int16)
        if heights is not None:  # the map's cells an object explains are that object, not a wall
            for mask in self._masks.values():
                labels[mask] = 0
        for label, item in self._objects.items():
            if heights is None or item.spans(*heights):
                labels[self._masks[label]] = label
        labels.setflags(write=False)
        return labels

    def blocked_at(self, z_m: float) -> NDArray[np.bool_]:
        """The cells where something crosses the horizontal plane at ``z_m`` (walls, objects spanning it): what
        a lidar scanning that plane can see, and what mapping with it can draw."""
        return self.caster_at(z_m).blocked

    def caster_at(self, z_m: float) -> GridCaster:
        """A ray caster through what crosses the horizontal plane at ``z_m`` (walls, objects spanning it): the
        lidar's view. The objects under the plane and the table tops above it are not in it."""
        caster = self._plane_casters.get(z_m)
        if caster is None:
            if all(item.spans(z_m, z_m) for item in self._objects.values()):
                caster = self.blocked_caster
            else:
                caster = GridCaster(self._labels((z_m, z_m)) != 0, self.resolution_m)
            self._plane_casters[z_m] = caster
        return caster

    def _layer(self, bottom_m: float, top_m: float) -> tuple[NDArray[np.int16], NDArray[np.float64]]:
        key = (bottom_m, top_m)
        layer = self._layers.get(key)
        if layer is None:
            if all(item.spans(bottom_m, top_m) for item in self._objects.values()):
                layer = (self.labels, self._edt_m)
            else:
                labels = self._labels(key)
                blocked = labels != 0
                edt = (ndimage.distance_transform_edt(~blocked) if blocked.any()
                       else np.full(blocked.shape, np.inf)) * self.resolution_m
                layer = (labels, edt)
            self._layers[key] = layer
        return layer

    def name_of(self, label: int) -> str:
        """What a label is, for collision reports."""
        if label == WALL:
            return "wall"
        item = self._objects.get(label)
        return item.name if item is not None else f"object {label}"

    def view_key(self, pose: Pose2D) -> tuple[float, float, float, object]:
        """What a sensor's view of the walls and furniture from ``pose`` depends on: the pose, to the bit, and this
        scene as it is now (its `revision`). A robot standing still has the same pose frame after frame, so the
        simulated cameras and lidar keep their last view while the key stays the same and add only the people
        and pets to it; furniture put down or taken away changes the key."""
        return (pose.x_m, pose.y_m, pose.yaw_rad, self.revision)

    # -- frames --------------------------------------------------------------------------------
    def to_grid_frame(self, x_m: float, y_m: float, yaw_rad: float) -> tuple[float, float, float]:
        """A world pose in the grid frame (metres from the grid's lower-left corner, yaw relative)."""
        o = self.map.origin
        dx, dy = x_m - o.x_m, y_m - o.y_m
        if o.yaw_rad:
            c, s = math.cos(o.yaw_rad), math.sin(o.yaw_rad)
            dx, dy = c * dx + s * dy, -s * dx + c * dy
        return dx, dy, yaw_rad - o.yaw_rad

    def cell_of(self, x_m: float, y_m: float) -> tuple[int, int] | None:
        """(row, col) of a world point, or None outside the grid."""
        gx, gy, _ = self.to_grid_frame(x_m, y_m, 0.0)
        row, col = math.floor(gy / self.resolution_m), math.floor(gx / self.resolution_m)
        h, w = self.labels.shape
        return (row, col) if 0 <= row < h and 0 <= col < w else None

    def in_drop_zone(self, x_m: float, y_m: float) -> bool:
        """Whether a point's cell is over a drop zone."""
        return self.drop_depth_at(x_m, y_m) > 0

    def drop_depth_at(self, x_m: float, y_m: float) -> float:
        """How far the floor drops at a point (to the cell: 5 cm in the shipped worlds); 0 outside the map."""
        cell = self.cell_of(x_m, y_m)
        return 0.0 if cell is None else float(self.drop_depth_m[cell])

    # -- bodies --------------------------------------------------------------------------------
    def _offsets(self, radius_m: float) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        cached = self._footprints.get(radius_m)
        if cached is None:
            reach = math.ceil(radius_m / self.resolution_m) + 1
            dr, dc = np.mgrid[-reach:reach + 1, -reach:reach + 1]
            cached = (dr.ravel().astype(np.intp), dc.ravel().astype(np.intp))
            self._footprints[radius_m] = cached
        return cached

    def clearance(self, x_m: float, y_m: float, radius_m: float) -> Contact:
        """Distance from a disc of ``radius_m`` at (x, y) to the nearest blocked cell (negative: inside).

        Only cells within reach of the disc are examined, so the answer is exact up to ``radius_m`` plus
        a cell; farther away the clearance is reported as that reach. Every object counts, whatever its height.
        """
        return self._clearance(self.labels, self._edt_m, x_m, y_m, radius_m)

    def body_clearance(self, x_m: float, y_m: float, body: RobotBody) -> Contact:
        """The smallest clearance of the robot's parts at (x, y), each against what is at its own heights; the
        contact names the object and the part (a table top meets the mast, not the base)."""
        best: Contact | None = None
        for part in body.parts:
            labels, edt = self._layer(part.bottom_m, part.top_m)
            contact = self._clearance(labels, edt, x_m, y_m, part.radius_m)
            if best is None or contact.clearance_m < best.clearance_m:
                best = Contact(contact.clearance_m, contact.what, part.name if contact.what else "")
        assert best is not None  # a body has at least its base
        return best

    def _clearance(self, labels: NDArray[np.int16], edt_m: NDArray[np.float64], x_m: float, y_m: float,
                   radius_m: float) -> Contact:
        res = self.resolution_m
        gx, gy, _ = self.to_grid_frame(x_m, y_m, 0.0)
        row0, col0 = math.floor(gy / res), math.floor(gx / res)
        reach = (math.ceil(radius_m / res) + 1) * res - radius_m
        h, w = labels.shape
        if 0 <= row0 < h and 0 <= col0 < w:
            # The exact distance is at least the centre-to-centre one minus two half cell diagonals.
            lower = float(edt_m[row0, col0]) - 1.4143 * res - radius_m
            if lower > reach:
                return Contact(reach, "")
        dr, dc = self._offsets(radius_m)
        rows, cols = row0 + dr, col0 + dc
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        rows, cols = rows[inside], cols[inside]
        lab = labels[rows, cols]
        hit = lab != 0
        if not hit.any():
            return Contact(reach, "")
        rows, cols, lab = rows[hit], cols[hit], lab[hit]
        # Nearest point of each cell's square to the centre.
        nx = np.minimum(np.maximum(gx, cols * res), (cols + 1) * res) - gx
        ny = np.minimum(np.maximum(gy, rows * res), (rows + 1) * res) - gy
        d = np.hypot(nx, ny)
        i = int(np.argmin(d))
        return Contact(min(float(d[i]) - radius_m, reach), self.name_of(int(lab[i])))
