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
        dist = self._floor_depth / self.col_cos[None, :].astype(np.float32)
        fog = np.exp(-dist / params.fog_m)[..., None]
        looks = np.stack([(color * fog + HAZE * (1.0 - fog)).astype(np.uint8) for color in (FLOOR_A, FLOOR_B, DROP)])
        #: The three looks as one table of pixels, look-major: a floor pixel is one gather from it, at
        #: ``look * floor pixels + its own index`` (cheaper than blending whole images with ``np.where``).
        self._floor_pixels = looks.reshape(-1, 3)
        self._floor_index = np.arange(looks.shape[1] * w, dtype=np.intp).reshape(looks.shape[1], w)

    def render(self, pose: Pose2D, scene: Scene, movers: Movers | None = None) -> NDArray[np.uint8]:
        """The image seen from the robot at ``pose``, with the moving obstacles as cylinders."""
        p = self.params
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        cam_x = pose.x_m + c * p.mount.x_m - s * p.mount.y_m
        cam_y = pose.y_m + s * p.mount.x_m + c * p.mount.y_m
        yaw = pose.yaw_rad + p.mount.yaw_rad
        gx, gy, gyaw = scene.to_grid_frame(cam_x, cam_y, yaw)
        img = self._background(scene, cam_x, cam_y, yaw)
        rays = gyaw + self.col_angles

        wall = scene.walls_caster.cast((gx, gy), rays, p.max_range_m)
        d_wall = wall.distance_m * self.col_cos  # perpendicular depth: straight walls stay straight
        shade = np.where(wall.side == 1, 0.82, 1.0)[:, None]
        self._paint(img, d_wall, np.full(p.width, scene.world.wall_height_m), scene.label_colors[1][None, :] * shade)

        d_furn = np.full(p.width, np.inf)
        if scene.furniture.any():
            furn = scene.furniture_caster.cast((gx, gy), rays, p.max_range_m)
            d_furn = np.where(furn.distance_m * self.col_cos < d_wall, furn.distance_m * self.col_cos, np.inf)
            labels = np.where(np.isfinite(d_furn), scene.labels[np.maximum(furn.row, 0), np.maximum(furn.col, 0)], 0)
            furn_top = scene.label_heights[labels]
            furn_bottom = scene.label_bottoms[labels]
            furn_color = scene.label_colors[labels] * np.where(furn.side == 1, 0.78, 1.0)[:, None]

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

        # Painter's order per column: the wall, then furniture and people far to near.
        if np.isfinite(d_furn).any():
            self._paint(img, np.where(d_furn >= d_mover, d_furn, np.inf), furn_top, furn_color, furn_bottom)
        if np.isfinite(d_mover).any():
            self._paint(img, d_mover, mover_top, mover_color)
        if np.isfinite(d_furn).any() and np.isfinite(d_mover).any():
            self._paint(img, np.where(d_furn < d_mover, d_furn, np.inf), furn_top, furn_color, furn_bottom)
        return img

    def _paint(self, img: NDArray[np.uint8], depth: NDArray[np.float64], top_m: NDArray[np.float64],
               color: NDArray[np.float64], bottom_m: NDArray[np.float64] | None = None) -> None:
        """Draw, in each column, a vertical span from ``bottom_m`` (the floor by default: a table top floats) to
        ``top_m`` at ``depth`` (inf: nothing)."""
        p = self.params
        if not np.isfinite(depth).any():
            return
        f = p.focal_px
        centre = p.height / 2 - 0.5
        with np.errstate(divide="ignore", invalid="ignore"):
            first = np.ceil(centre - f * (top_m - p.height_m) / depth)
            last = np.floor(centre + f * (p.height_m - (0.0 if bottom_m is None else bottom_m)) / depth)
        visible = np.isfinite(depth)
        first = np.where(visible, first, p.height).astype(np.int32)
        last = np.where(visible, last, -1).astype(np.int32)
        fog = np.exp(-np.where(visible, depth, 0.0) / p.fog_m)[:, None]
        col = (color * fog + HAZE * (1.0 - fog)).astype(np.uint8)
        # One slice per column: a few microseconds each, where a whole-image row mask and a masked copy of
        # all 480x640x3 bytes cost several milliseconds per span set (the camera runs at 10 Hz in every
        # simulated robot).
        start = np.clip(first, 0, p.height).tolist()
        stop = (np.clip(last, -1, p.height - 1) + 1).tolist()
        for j, (a, b) in enumerate(zip(start, stop, strict=True)):
            if b > a:
                img[a:b, j] = col[j]

    def _background(self, scene: Scene, cam_x: float, cam_y: float, yaw: float) -> NDArray[np.uint8]:
        """Ceiling above the horizon, tiled floor (dark over drop zones) below, both faded with distance."""
        p = self.params
        img = np.empty((p.height, p.width, 3), dtype=np.uint8)
        img[:self._n_sky] = self._ceiling
        # World position of the floor seen by each pixel below the horizon.
        c, s = np.float32(math.cos(yaw)), np.float32(math.sin(yaw))
        fx = np.float32(cam_x) + self._floor_depth * (c - self._col_tan * s)[None, :]
        fy = np.float32(cam_y) + self._floor_depth * (s + self._col_tan * c)[None, :]
        # Which look each floor pixel has: tile 0 or 1 of the checkerboard, 2 over a drop.
        look = ((np.floor(fx * 2.0).astype(np.int32) + np.floor(fy * 2.0).astype(np.int32)) & 1).astype(np.intp)
        if scene.drop_bounds_m is not None:
            # Only the floor points near a drop zone can be over one: look their cells up (the whole floor's
            # would cost more than the rest of the background together).
            x0, y0, x1, y1 = scene.drop_bounds_m
            near = np.nonzero((fx >= x0) & (fx <= x1) & (fy >= y0) & (fy <= y1))
            row, col = scene.map.world_to_cell(fx[near], fy[near])
            h, w = scene.drop_mask.shape
            # Off-map points land in the padded border, which has no drop.
            flat = (np.clip(row, -1, h) + 1) * (w + 2) + np.clip(col, -1, w) + 1
            drop = scene.drop_mask_padded.ravel().take(flat)
            look[near[0][drop], near[1][drop]] = 2
        look *= self._floor_index.size
        look += self._floor_index
        np.take(self._floor_pixels, look, axis=0, out=img[self._n_sky:])
        return img
