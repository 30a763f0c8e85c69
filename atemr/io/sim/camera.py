"""The front camera: a first-person RGB view rendered from the scene, cheap enough to stream at 10 fps.

A ray-casting renderer in the manner of early 3-D games: one ray per image column, cast through the
grid for walls and for furniture separately and against the moving obstacles' circles, so each column
knows the distance to the nearest wall, object and person. Each is drawn as a vertical span whose top
and bottom come from a pinhole projection of its height (walls extruded to the wall height, furniture to
its own height, people as cylinders), with a per-pixel depth test so nearer things hide farther ones and
a low sofa does not hide the wall above it. The floor is a checkerboard of 0.5 m tiles (so motion is
visible), dark over drop zones; faces lit by their orientation and everything dimmed with distance.

Everything is whole-image numpy: the per-frame constants (column angles, row slopes) are computed once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.io.sim.movers import Movers
from atemr.io.sim.raycast import cast_circles
from atemr.io.sim.scene import Scene
from atemr.msgs import Pose2D

CEILING = np.array([235.0, 235.0, 228.0])
FLOOR_A = np.array([176.0, 150.0, 118.0])
FLOOR_B = np.array([160.0, 134.0, 102.0])
DROP = np.array([25.0, 25.0, 30.0])
#: What distant things fade into (exponential fog: ``exp(-distance / fog_m)`` of an object's own colour).
HAZE = np.array([165.0, 162.0, 158.0])
#: One RGB pixel as a single 3-byte item: a masked copy of whole pixels then moves runs of them at once (a mask
#: broadcast over the three channels makes numpy copy byte by byte, ten times slower).
PIXEL = np.dtype((np.void, 3))


@dataclass(frozen=True)
class CameraParams:
    """A forward-looking camera on the mast; defaults give the thesis's 640x480 stream."""

    width: int = 640
    height: int = 480
    hfov_deg: float = 69.0
    height_m: float = 1.0
    mount: Pose2D = field(default_factory=lambda: Pose2D(0.12, 0.0, 0.0))
    max_range_m: float = 15.0
    fog_m: float = 15.0

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 4096 and 16 <= self.height <= 4096):
            raise ConfigError(f"image size must be within 16..4096, got {self.width}x{self.height}", path="camera")
        if not 10.0 <= self.hfov_deg <= 170.0:
            raise ConfigError(f"must be within 10..170 degrees, got {self.hfov_deg}", path="camera.hfov_deg")
        if not 0.05 <= self.height_m <= 3.0:
            raise ConfigError(f"must be within 0.05..3 m, got {self.height_m}", path="camera.height_m")

    @property
    def focal_px(self) -> float:
        return (self.width / 2) / math.tan(math.radians(self.hfov_deg) / 2)


@dataclass
class _StaticView:
    """What a camera at one pose sees of what does not move (`Camera._static_view`; arrays read-only)."""

    #: The `Scene.view_key` it was made for.
    key: tuple[float, float, float, object]
    #: The background with the walls painted: where people and the furniture around them are painted.
    walls: NDArray[np.uint8]
    #: Each column's depth to the wall.
    d_wall: NDArray[np.float64]
    #: The furniture seen in each column: depth (inf: none), top, colour, bottom; None when none is in view.
    furniture: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None
    #: The picture with nobody in view (walls and furniture), once a second frame at the pose needed it.
    finished: NDArray[np.uint8] | None = None


class Camera:
    """Renders HxWx3 uint8 images of the scene from a robot pose."""

    def __init__(self, params: CameraParams) -> None:
        self.params = params
        w, h, f = params.width, params.height, params.focal_px
        u = np.arange(w, dtype=np.float64) + 0.5
        #: Column angle relative to the optical axis (left positive) and the factor turning ray length into depth.
        self.col_angles = np.arctan((w / 2 - u) / f)
        self.col_cos = np.cos(self.col_angles)
        self._col_tan = np.tan(self.col_angles).astype(np.float32)
        v = np.arange(h, dtype=np.float64) + 0.5
        #: Vertical slope of each row's ray (up positive): a point at depth D and height z is on row v when
        #: ``z - cam_z = slope[v] * D``.
        self.row_slope = ((h / 2 - v) / f)[:, None]
        #: Row numbers as a column, to compare with each column's span at once (int32: half the bytes of intp).
        self._rows = np.arange(h, dtype=np.int32)[:, None]
        below = self.row_slope[:, 0] < 0
        self._n_sky = int(np.count_nonzero(~below))
        # Everything about the background that does not depend on the pose, computed once: the ceiling,
        # and the floor's three looks (two tiles, a drop) already faded with each pixel's distance.
        fade = np.clip(1.0 - 0.35 * np.abs(self.row_slope[~below, 0]), 0.7, 1.0)
        self._ceiling = np.ascontiguousarray(
            np.broadcast_to((CEILING[None, :] * fade[:, None])[:, None, :], (self._n_sky, w, 3))
        ).astype(np.uint8)
        #: Depth of the floor seen by each floor row.
        self._floor_depth = (params.height_m / -self.row_slope[below, 0]).astype(np.float32)[:, None]
        #: Their negatives, increasing down the image: what `np.searchsorted` needs.
        self._neg_floor_depth = -self._floor_depth[:, 0].astype(np.float64)
        dist = self._floor_depth / self.col_cos[None, :].astype(np.float32)
        fog = np.exp(-dist / params.fog_m)[..., None]
        #: The floor's three looks as whole images (tile A, tile B, a drop): a frame picks, per pixel, one of
        #: the first two by the checkerboard's parity (one ``np.where`` on bytes) and patches the drops in.
        self._floor_a, self._floor_b, self._floor_drop = (
            (color * fog + HAZE * (1.0 - fog)).astype(np.uint8) for color in (FLOOR_A, FLOOR_B, DROP))
        #: The last `_static_view` (a standing robot's camera sees it again and again).
        self._static: _StaticView | None = None

    def render(self, pose: Pose2D, scene: Scene, movers: Movers | None = None) -> NDArray[np.uint8]:
        """The image seen from the robot at ``pose``, with the moving obstacles as cylinders."""
        p = self.params
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        cam_x = pose.x_m + c * p.mount.x_m - s * p.mount.y_m
        cam_y = pose.y_m + s * p.mount.x_m + c * p.mount.y_m
        yaw = pose.yaw_rad + p.mount.yaw_rad
        view, reused = self._static_view(pose, scene, (cam_x, cam_y, yaw))
        d_wall = view.d_wall

        d_mover = np.full(p.width, np.inf)
        if movers is not None and len(movers.items):
            centres, radii = movers.centres, movers.radii
            world_rays = yaw + self.col_angles
            d, which = cast_circles((cam_x, cam_y), world_rays, centres, radii, p.max_range_m)
            idx = np.maximum(which, 0)
            # Shade cylinders by how squarely the ray meets them: brighter in the middle.
            hx = cam_x + d * np.cos(world_rays) - centres[idx, 0]
            hy = cam_y + d * np.sin(world_rays) - centres[idx, 1]
            facing = np.abs(hx * np.cos(world_rays) + hy * np.sin(world_rays))
            cyl = 0.6 + 0.4 * np.clip(facing / np.maximum(radii[idx], 1e-9), 0.0, 1.0)
            d_mover = np.where(d * self.col_cos < d_wall, d * self.col_cos, np.inf)
            mover_top = movers.heights[idx]
            mover_color = movers.colors[idx] * cyl[:, None]
        furniture = view.furniture
        if not np.isfinite(d_mover).any():  # nobody in view: the picture is what does not move
            if view.finished is not None:
                return view.finished.copy()
            img = view.walls.copy()
            if furniture is not None:
                d_furn, furn_top, furn_color, furn_bottom = furniture
                self._paint(img, d_furn, furn_top, furn_color, furn_bottom)
            if not reused:  # a moving robot's view is seen once: nothing to keep
                return img
            img.setflags(write=False)
            view.finished = img
            return img.copy()

        # Painter's order per column: the wall, then furniture and people far to near: furniture behind a person
        # first, the people, then the rest of the furniture (in front of a person, or in a column with nobody).
        img = view.walls.copy()
        if furniture is not None:
            d_furn, furn_top, furn_color, furn_bottom = furniture
            self._paint(img, np.where(d_furn >= d_mover, d_furn, np.inf), furn_top, furn_color, furn_bottom)
        self._paint(img, d_mover, mover_top, mover_color)
        if furniture is not None:
            self._paint(img, np.where(d_furn < d_mover, d_furn, np.inf), furn_top, furn_color, furn_bottom)
        return img

    def _static_view(self, pose: Pose2D, scene: Scene, camera: tuple[float, float, float]
                     ) -> tuple[_StaticView, bool]:
        """What does not move, seen from ``pose``: the background with the walls painted and the furniture to
        paint around people; and whether it was kept from an earlier frame (the last view is kept for its
        `Scene.view_key`: a robot standing still, a carer watching it). Every step is the one a fresh view takes,
        in the same order, so the pictures are the same."""
        kept = self._static
        key = scene.view_key(pose)
        if kept is not None and kept.key == key:
            return kept, True
        p = self.params
        cam_x, cam_y, yaw = camera
        gx, gy, gyaw = scene.to_grid_frame(cam_x, cam_y, yaw)
        img = self._background(scene, cam_x, cam_y, yaw)
        rays = gyaw + self.col_angles

        wall = scene.walls_caster.cast((gx, gy), rays, p.max_range_m)
        d_wall = wall.distance_m * self.col_cos  # perpendicular depth: straight walls stay straight
        shade = np.where(wall.side == 1, 0.82, 1.0)[:, None]
        self._paint(img, d_wall, np.full(p.width, scene.world.wall_height_m), scene.label_colors[1][None, :] * shade)

        furniture = None
        if scene.furniture.any():
            # Furniture behind the wall is never drawn: each furniture ray stops at its wall.
            furn = scene.furniture_caster.cast((gx, gy), rays, np.minimum(wall.distance_m, p.max_range_m))
            d_furn = np.where(furn.distance_m * self.col_cos < d_wall, furn.distance_m * self.col_cos, np.inf)
            if np.isfinite(d_furn).any():
                labels = np.where(np.isfinite(d_furn), scene.labels[np.maximum(furn.row, 0),
                                                                    np.maximum(furn.col, 0)], 0)
                furniture = (d_furn, scene.label_heights[labels],
                             scene.label_colors[labels] * np.where(furn.side == 1, 0.78, 1.0)[:, None],
                             scene.label_bottoms[labels])
        for array in (img, d_wall):
            array.setflags(write=False)
        self._static = _StaticView(key, img, d_wall, furniture)
        return self._static, False

    def _paint(self, img: NDArray[np.uint8], depth: NDArray[np.float64], top_m: NDArray[np.float64],
               color: NDArray[np.float64], bottom_m: NDArray[np.float64] | None = None) -> None:
        """Draw, in each column, a vertical span from ``bottom_m`` (the floor by default: a table top floats) to
        ``top_m`` at ``depth`` (inf: nothing).

        All columns at once: a mask of the pixels inside their column's span, over the box the spans cover
        only (a chair is a few columns), and one masked copy of the columns' colours into it. A slice per
        column in a Python loop cost 3 ms a frame at 640 columns; this costs a tenth of that.
        """
        p = self.params
        visible = np.isfinite(depth)
        cols = np.flatnonzero(visible)
        if not cols.size:
            return
        c0, c1 = int(cols[0]), int(cols[-1]) + 1
        vis = visible[c0:c1]
        d = np.where(vis, np.maximum(depth[c0:c1], 1e-9), 1.0)  # a ray starting in a wall (0) still draws
        f = p.focal_px
        centre = p.height / 2 - 0.5
        bottom = 0.0 if bottom_m is None else bottom_m[c0:c1]
        first = np.ceil(centre - f * (top_m[c0:c1] - p.height_m) / d)
        last = np.floor(centre + f * (p.height_m - bottom) / d)
        start = np.where(vis, np.clip(first, 0, p.height), 0).astype(np.int32)
        stop = np.where(vis, np.clip(last + 1, 0, p.height), 0).astype(np.int32)
        r0, r1 = int(start[vis].min()), int(stop[vis].max())
        if r1 <= r0:
            return
        # Inside the span when 0 <= row - start < its length: one subtraction and one unsigned comparison.
        inside = (self._rows[r0:r1] - start).view(np.uint32) < np.maximum(stop - start, 0).view(np.uint32)
        fog = np.exp(-np.where(visible, depth, 0.0)[c0:c1] / p.fog_m)[:, None]
        col = (color[c0:c1] * fog + HAZE * (1.0 - fog)).astype(np.uint8)
        np.copyto(_pixels(img)[r0:r1, c0:c1], _pixels(col)[None], where=inside)

    def _background(self, scene: Scene, cam_x: float, cam_y: float, yaw: float) -> NDArray[np.uint8]:
        """Ceiling above the horizon, tiled floor (dark over drop zones) below, both faded with distance."""
        p = self.params
        img = np.empty((p.height, p.width, 3), dtype=np.uint8)
        img[:self._n_sky] = self._ceiling
        # Twice the world position of the floor seen by each pixel below the horizon (tiles are half a metre:
        # the tile index is its floor). Scaling by 2 is exact in binary floating point, so this is the same
        # number as doubling the position afterwards.
        c, s = np.float32(math.cos(yaw)), np.float32(math.sin(yaw))
        # Each column's floor step per metre of depth.
        ax, ay = c - self._col_tan * s, s + self._col_tan * c
        fx2 = np.multiply(self._floor_depth, (2 * ax)[None, :])
        fx2 += np.float32(2 * np.float32(cam_x))
        fy2 = np.multiply(self._floor_depth, (2 * ay)[None, :])
        fy2 += np.float32(2 * np.float32(cam_y))
        # Which tile each floor pixel sees: A or B of the checkerboard, by the parity of its tile indices.
        tile = np.floor(fx2).astype(np.int32)
        tile += np.floor(fy2).astype(np.int32)
        tile &= 1
        floor = img[self._n_sky:]
        np.copyto(floor, self._floor_a)
        np.copyto(_pixels(floor), _pixels(self._floor_b), where=tile.astype(bool))
        if scene.drop_bounds_m is not None:
            self._drops(floor, scene, (cam_x, cam_y, ax, ay), fx2, fy2)
        return img

    def _drops(self, floor: NDArray[np.uint8], scene: Scene,
               rays: tuple[float, float, NDArray[np.float32], NDArray[np.float32]],
               fx2: NDArray[np.float32], fy2: NDArray[np.float32]) -> None:
        """Darken the floor pixels over a drop zone (``rays``: the camera's x and y and each column's floor step
        per metre of depth along x and y; ``fx2``, ``fy2``: twice each floor pixel's world position).

        Only the pixels whose floor point lies in the box round the drops can be over one. Each column looks
        at the floor along a straight line, so that box is one run of its rows, found by a slab test per
        column and a search in the rows' (sorted) depths: a view without a drop in it costs next to nothing,
        where testing every floor pixel against the box cost a millisecond a frame.
        """
        assert scene.drop_bounds_m is not None
        x0, y0, x1, y1 = scene.drop_bounds_m
        cam_x, cam_y, ax, ay = rays
        lo, hi = np.zeros(self.params.width), np.full(self.params.width, np.inf)
        for o, along, a, b in ((cam_x, ax, x0, x1), (cam_y, ay, y0, y1)):
            step = along.astype(np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                t1, t2 = (a - o) / step, (b - o) / step
            flat = step == 0  # parallel to this slab: inside it all along, or never
            t1 = np.where(flat, np.where(a <= o <= b, -np.inf, np.inf), t1)
            t2 = np.where(flat, np.where(a <= o <= b, np.inf, -np.inf), t2)
            lo, hi = np.maximum(lo, np.minimum(t1, t2)), np.minimum(hi, np.maximum(t1, t2))
        # Floor rows run from far to near: their depths decrease. A row more on each side absorbs rounding.
        neg = self._neg_floor_depth
        start = np.maximum(np.searchsorted(neg, -hi, "left") - 1, 0)
        stop = np.where(hi >= lo, np.minimum(np.searchsorted(neg, -lo, "right") + 1, neg.size), 0)
        length = np.maximum(stop - start, 0)
        cols = np.flatnonzero(length)
        if not cols.size:
            return
        c0, c1 = int(cols[0]), int(cols[-1]) + 1
        r0, r1 = int(start[cols].min()), int(stop[cols].max())
        rows = np.arange(r0, r1, dtype=np.int64)[:, None]
        near = np.nonzero((rows - start[c0:c1]).view(np.uint64) < length[c0:c1].astype(np.uint64))
        r, q = near[0] + r0, near[1] + c0
        row, col = scene.map.world_to_cell(fx2[r, q] * np.float32(0.5), fy2[r, q] * np.float32(0.5))
        h, w = scene.drop_mask.shape
        # Off-map points land in the padded border, which has no drop.
        drop = scene.drop_mask_padded.ravel().take((np.clip(row, -1, h) + 1) * (w + 2) + np.clip(col, -1, w) + 1)
        r, q = r[drop], q[drop]
        floor[r, q] = self._floor_drop[r, q]


def _pixels(rgb: NDArray[np.uint8]) -> NDArray[np.void]:
    """An (..., 3) uint8 array seen as (...) whole pixels (`PIXEL`), sharing its memory."""
    out: NDArray[np.void] = rgb.view(PIXEL)[..., 0]
    return out
