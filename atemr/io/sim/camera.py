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
        v = np.arange(h, dtype=np.float64) + 0.5
        #: Vertical slope of each row's ray (up positive): a point at depth D and height z is on row v when
        #: ``z - cam_z = slope[v] * D``.
        self.row_slope = ((h / 2 - v) / f)[:, None]
        below = self.row_slope[:, 0] < 0
        self._floor_rows = np.nonzero(below)[0]
        #: Depth of the floor seen by each floor row.
        self._floor_depth = (params.height_m / -self.row_slope[below, 0])[:, None]

    def render(self, pose: Pose2D, scene: Scene, movers: Movers | None = None) -> NDArray[np.uint8]:
        """The image seen from the robot at ``pose``, with the moving obstacles as cylinders."""
        p = self.params
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        cam_x = pose.x_m + c * p.mount.x_m - s * p.mount.y_m
        cam_y = pose.y_m + s * p.mount.x_m + c * p.mount.y_m
        yaw = pose.yaw_rad + p.mount.yaw_rad
        gx, gy, gyaw = scene.to_grid_frame(cam_x, cam_y, yaw)
        h, w = p.height, p.width
        cam_z = p.height_m

        img = self._background(scene, cam_x, cam_y, yaw)
        zbuf = np.full((h, w), np.inf)
        layers: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]] = []

        wall = scene.walls_caster.cast((gx, gy), gyaw + self.col_angles, p.max_range_m)
        shade = np.where(wall.side == 1, 0.82, 1.0)
        wall_color = np.asarray(scene.label_colors[1])[None, :] * shade[:, None]
        layers.append((wall.distance_m, np.full(w, scene.world.wall_height_m), wall_color))

        if scene.furniture.any():
            furn = scene.furniture_caster.cast((gx, gy), gyaw + self.col_angles, p.max_range_m)
            hit = np.isfinite(furn.distance_m)
            labels = np.where(hit, scene.labels[np.maximum(furn.row, 0), np.maximum(furn.col, 0)], 0)
            fshade = np.where(furn.side == 1, 0.78, 1.0)
            layers.append((furn.distance_m, scene.label_heights[labels], scene.label_colors[labels] * fshade[:, None]))

        if movers is not None and len(movers.items):
            centres, radii, heights, colors = movers.centres, movers.radii, movers.heights, movers.colors
            d, which = cast_circles((cam_x, cam_y), yaw + self.col_angles, centres, radii, p.max_range_m)
            idx = np.maximum(which, 0)
            # Shade cylinders by how squarely the ray meets them: brighter in the middle.
            hx = cam_x + d * np.cos(yaw + self.col_angles) - centres[idx, 0]
            hy = cam_y + d * np.sin(yaw + self.col_angles) - centres[idx, 1]
            facing = np.abs(hx * np.cos(yaw + self.col_angles) + hy * np.sin(yaw + self.col_angles))
            cyl = 0.6 + 0.4 * np.clip(facing / np.maximum(radii[idx], 1e-9), 0.0, 1.0)
            cyl = np.where(np.isfinite(d), cyl, 1.0)
            layers.append((d, heights[idx], colors[idx] * cyl[:, None]))

        for dist, top, color in layers:
            depth = dist * self.col_cos  # perpendicular depth: straight walls stay straight
            rel = self.row_slope * depth[None, :]
            mask = (rel >= -cam_z) & (rel <= (top - cam_z)[None, :]) & (depth[None, :] < zbuf)
            zbuf = np.where(mask, depth[None, :], zbuf)
            fog = np.exp(-depth / p.fog_m)[:, None]
            col = (color * fog + HAZE * (1.0 - fog)).astype(np.float32)
            rows, cols = np.nonzero(mask)
            img[rows, cols] = col[cols]
        return img.astype(np.uint8)

    def _background(self, scene: Scene, cam_x: float, cam_y: float, yaw: float) -> NDArray[np.float32]:
        """Ceiling above the horizon, tiled floor (dark over drop zones) below, both dimmed with distance."""
        p = self.params
        img = np.empty((p.height, p.width, 3), dtype=np.float32)
        horizon_fade = np.clip(1.0 - 0.35 * np.abs(self.row_slope[:, 0]), 0.7, 1.0)
        img[:] = (CEILING[None, :] * horizon_fade[:, None])[:, None, :]
        depth = self._floor_depth  # (rows, 1)
        dist = depth / self.col_cos[None, :]
        ang = yaw + self.col_angles[None, :]
        fx = cam_x + dist * np.cos(ang)
        fy = cam_y + dist * np.sin(ang)
        tile = ((np.floor(fx * 2.0) + np.floor(fy * 2.0)) % 2.0)[..., None]
        floor = FLOOR_A * (1 - tile) + FLOOR_B * tile
        row, col = scene.map.world_to_cell(fx, fy)
        inside = scene.map.contains(row, col)
        drop = np.zeros(fx.shape, dtype=bool)
        drop[inside] = scene.drop_mask[row[inside], col[inside]]
        floor = np.where(drop[..., None], DROP, floor)
        fog = np.exp(-dist / p.fog_m)[..., None]
        img[self._floor_rows] = floor * fog + HAZE * (1.0 - fog)
        return img
