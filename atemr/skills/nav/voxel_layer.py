"""The depth camera's obstacle layer: a voxel grid over the costmap, marked and cleared from depth images.

What the lidar cannot see (a table top at 0.72 m, a shelf, a shoe under its plane) the depth camera can. Each
frame becomes a point cloud in the base frame (`atemr.skills.depth_cloud`, the camera's mounting pose), then
in the map frame from the robot's pose. A point counts when it lies between ``floor_margin_m`` (below: the
floor) and ``max_height_m`` (the robot's height plus a margin: above it nothing can touch the robot). The
grid has the costmap's cells and ``z_resolution_m`` layers between those heights (Nav2's voxel layer):

1. **clear**: a ray that returns from beyond a marked voxel passed through it, so the voxel is empty: a chair
   that was carried away disappears, and a ray that passes over a shoe at 0.9 m does not forget the shoe (its
   voxel is lower down). The rays are traced from the voxels' side: each marked voxel in reach is projected
   into the image and the pixel whose ray crosses it is read (`VoxelLayer._clear`);
2. **mark**: the voxels that hold at least ``min_points`` points within ``mark_range_m`` (noise grows with
   depth, and a lone flying pixel is no obstacle) are set; points within ``wall_match_m`` (plus
   ``wall_match_per_m`` per metre of range) of a mapped obstacle are that obstacle seen with depth noise and
   some pose error, and are not marked, as the lidar layer does (else every wall would narrow a doorway); nor
   are points within ``lidar_margin_m`` of what the lidar sees now (the frame's ``scan``): those are the lidar
   layer's, which clears them with every scan and tracks them when they walk. Kept here they would stay behind
   as a trail wherever a person walked out of the camera's view. Nothing is lost: the costmap keeps the
   robot's centre 0.4 m from the lidar's obstacles and its widest part above the base reaches 0.13 m, so
   nothing within 0.27 m of them can touch it;
3. **clear by the lidar**: a voxel wholly above the lidar's plane (``lidar_height_m``) and at most
   ``lidar_band_m`` above it, in a cell a beam of the frame's scan passes through (its return is farther by
   ``clear_margin_m``), is empty: anything there standing on the floor would cross the plane and return that
   beam. The far edge of a walking cat's back (0.35 m), beyond ``lidar_margin_m`` of its returns and out of the
   camera's view once the cat walked on, is forgotten at the next scan instead of closing a passage until the
   decay; a table top or shelf above the band and a shoe under the plane are the camera's alone. A thing hanging
   just above the plane over free floor is forgotten too while out of view (the camera marks it again whenever
   it sees it);
4. **project**: a cell is an obstacle when any voxel of its column is, and the costmap gets those columns
   (`Costmap.set_voxel_columns`): the planners keep away from them like from the lidar's.

The layer keeps its voxels between frames: what has left the camera's view (the table top right in front of
the mast, closer than the camera's 0.3 m) stays marked until a ray passes through it, or until ``decay_s``
after it was last seen (the spatio-temporal voxel layer's decay): something that moved while out of view (a
cat the lidar lost behind the bed) does not stay in the costmap for good. Memory of a table top the robot
stands at outlives the decay anyway: its farther parts are seen again every frame, and as the robot creeps on
they are what the stop zone meets. `clearance` gives the motion pipeline's slow and stop zones the nearest
marked cell ahead, behind and beside the robot, so a table top in front of the mast stops the robot as a wall
in front of the base does.

Vectorised numpy over the frame's pixels and the marked voxels, and one compiled loop (`_marks`, numba) from a
pixel's depth to its voxel where numpy needed a dozen passes over every point; no I/O, no clock.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from atemr.errors import NavigationError
from atemr.msgs import CameraMount, DepthImage, LaserScan, Pose2D
from atemr.skills.body import RobotBody
from atemr.skills.depth_cloud import DepthProjector, mount_rotation
from atemr.skills.nav.costmap import Costmap
from atemr.skills.ramp import Clearance

F32 = NDArray[np.float32]


@dataclass(frozen=True)
class VoxelLayerParams:
    """Heights, ranges and sampling of the depth obstacle layer (defaults: KAY and its D415)."""

    floor_margin_m: float = 0.05
    max_height_m: float = 1.25
    z_resolution_m: float = 0.1
    mark_range_m: float = 2.5
    min_points: int = 3
    stride: int = 2
    #: A voxel is empty when the ray through it returns from at least this much farther (half a voxel's
    #: diagonal and the camera's noise at a couple of metres).
    clear_margin_m: float = 0.1
    wall_match_m: float = 0.08
    wall_match_per_m: float = 0.02
    #: Points this close (in plan) to a return of the frame's lidar scan are the lidar layer's (people, legs).
    lidar_margin_m: float = 0.25
    #: The lidar's scan plane above the floor, and how far above it the lidar's free beams clear the voxels.
    lidar_height_m: float = 0.2
    lidar_band_m: float = 0.25
    #: A column not marked again for this long is forgotten (what moved while out of view).
    decay_s: float = 10.0
    #: How far round the robot `clearance` looks for marked cells.
    zone_radius_m: float = 1.5

    def __post_init__(self) -> None:
        for name in ("max_height_m", "z_resolution_m", "mark_range_m", "zone_radius_m", "decay_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise NavigationError(f"voxel layer: {name} must be a finite number > 0, got {value!r}")
        if not (math.isfinite(self.floor_margin_m) and 0 <= self.floor_margin_m < self.max_height_m):
            raise NavigationError(f"voxel layer: need 0 <= floor_margin_m < max_height_m, got {self.floor_margin_m}")
        if self.min_points < 1 or self.stride < 1 or not min(self.wall_match_m, self.wall_match_per_m,
                                                                   self.clear_margin_m, self.lidar_margin_m,
                                                                   self.lidar_height_m, self.lidar_band_m) >= 0:
            raise NavigationError("voxel layer: min_points and stride >= 1; wall_match_m, clear_margin_m, "
                                  "lidar_margin_m, lidar_height_m and lidar_band_m >= 0")

    @classmethod
    def for_body(cls, body: RobotBody, margin_m: float = 0.1) -> VoxelLayerParams:
        """The layer for a robot: obstacles up to its height plus ``margin_m``."""
        return cls(max_height_m=body.height_m + margin_m)

    @property
    def layers(self) -> int:
        return max(1, math.ceil((self.max_height_m - self.floor_margin_m) / self.z_resolution_m))

    @property
    def lidar_layers(self) -> tuple[int, int]:
        """The layers [first, end) wholly between the lidar's plane and ``lidar_band_m`` above it."""
        eps = 1e-9
        first = math.ceil((self.lidar_height_m - self.floor_margin_m) / self.z_resolution_m - eps)
        end = math.floor((self.lidar_height_m + self.lidar_band_m - self.floor_margin_m) / self.z_resolution_m + eps)
        return max(first, 0), min(max(end, 0), self.layers)


class VoxelLayer:
    """The voxel grid of one costmap (same cells), fed with depth images; see the module docstring."""

    def __init__(self, costmap: Costmap, params: VoxelLayerParams | None = None) -> None:
        self.costmap = costmap
        self.params = params or VoxelLayerParams()
        p = self.params
        self.resolution_m = costmap.resolution_m
        self.shape = costmap.shape
        self.voxels = np.zeros((*self.shape, p.layers), dtype=bool)
        self._voxels_flat = self.voxels.reshape(-1)  # a view: (row * width + col) * layers + layer
        self.columns = np.zeros(self.shape, dtype=bool)
        #: When each cell was last marked (image time), for the decay.
        self._seen_t = np.full(self.shape, -np.inf, dtype=np.float64)
        self._projector = DepthProjector(p.stride)
        self._mount: CameraMount | None = None
        self._mount_rotation = np.eye(3)
        rows, cols = np.indices(self.shape)
        xs, ys = costmap.map.cell_to_world(rows, cols)
        #: Distance from each cell to the map's obstacles: points this near one (by range) are that obstacle.
        self._static_flat = costmap.static_distance_at(xs, ys).astype(np.float32).reshape(-1)
        self._min_match = max(p.wall_match_m, 1.5 * self.resolution_m)
        load_compiled()
        self._clears_seen = costmap.clears

    def obstacle_points(self) -> NDArray[np.float64]:
        """The centres of the cells the layer holds as obstacles now, (N, 2) in the map frame: what the
        dashboard draws over the map beside the lidar's scan."""
        rows, cols = np.nonzero(self.columns)
        xs, ys = self.costmap.map.cell_to_world(rows, cols)
        return np.column_stack([xs, ys]).astype(np.float64)

    # -- frames ----------------------------------------------------------------------------------------------
    def _grid_frame(self, pose: Pose2D) -> tuple[float, float, float, float]:
        """(cos, sin, x, y) taking base-frame (x, y) to grid-frame metres (from the grid's lower-left corner)."""
        o = self.costmap.map.origin
        dx, dy = pose.x_m - o.x_m, pose.y_m - o.y_m
        co, so = math.cos(o.yaw_rad), math.sin(o.yaw_rad)
        gx, gy = co * dx + so * dy, -so * dx + co * dy
        yaw = pose.yaw_rad - o.yaw_rad
        return math.cos(yaw), math.sin(yaw), gx, gy

    def _flat(self, pts: F32, frame: tuple[float, float, float, float]) -> tuple[NDArray[np.int32], NDArray[np.bool_]]:
        """Flat voxel index of base-frame points ((row * width + col) * layers + layer) and whether each is in the
        grid and between the heights. Indices are floored by truncating a value shifted by one (cheaper than
        ``floor``; anything below 0 stays below 0)."""
        c, s, gx, gy = frame
        p = self.params
        inv_res = np.float32(1.0 / self.resolution_m)
        x, y = pts[..., 0], pts[..., 1]
        col = ((np.float32(c) * x - np.float32(s) * y + np.float32(gx)) * inv_res + 1).astype(np.int32) - 1
        row = ((np.float32(s) * x + np.float32(c) * y + np.float32(gy)) * inv_res + 1).astype(np.int32) - 1
        layer = ((pts[..., 2] - np.float32(p.floor_margin_m)) * np.float32(1.0 / p.z_resolution_m) + 1
                 ).astype(np.int32) - 1
        h, w = self.shape
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w) & (layer >= 0) & (layer < p.layers)
        return (row * w + col) * p.layers + layer, inside

    # -- the update --------------------------------------------------------------------------------------------
    def update(self, image: DepthImage, pose: Pose2D, scan: LaserScan | None = None) -> int:
        """Clear along the frame's rays, mark its points, hand the columns to the costmap; returns how many
        cells hold an obstacle. ``pose`` is the base's map pose when the frame was taken; ``scan`` the lidar's
        latest, whose obstacles this layer leaves to the lidar's layer."""
        if not all(math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad)):
            raise NavigationError(f"voxel layer: robot pose must be finite, got {pose}")
        if self.costmap.clears != self._clears_seen:  # a recovery cleared the costmap: forget the voxels too
            self._clears_seen = self.costmap.clears
            self.voxels[:] = False
            self.columns[:] = False
        frame = self._grid_frame(pose)
        cleared = self._clear(image, frame)
        if scan is not None:
            cleared = np.concatenate([cleared, self._clear_by_lidar(scan, frame)])
        marked = self._mark(image, frame, scan)
        self._seen_t.reshape(-1)[marked // self.params.layers] = image.t
        self._project(np.concatenate([cleared, marked, self._decay(image.t)]))
        self.costmap.set_voxel_columns(self.columns)
        return int(self.columns.sum())

    def _clear(self, image: DepthImage, frame: tuple[float, float, float, float]) -> NDArray[np.int32]:
        """Empty the marked voxels the frame sees through; returns the flat indices of the voxels cleared.

        Ray tracing from the voxels' side: each marked voxel within the camera's reach is projected into the
        image (the pinhole model), and the pixel whose ray passes through its centre is read. A return farther
        than the voxel (by ``clear_margin_m``) means that ray went through the voxel into free space beyond, so
        the voxel is empty now. No data (0), a voxel behind the camera or outside the image clears nothing.
        One test per marked voxel instead of a walk along every pixel's ray: the same answer for every voxel a
        pixel's ray crosses at its centre, at a cost that does not grow with the image."""
        p = self.params
        res = self.resolution_m
        c, s, gx, gy = frame
        mount = image.mount
        # the marked voxels in the window of cells the camera can see
        cam_x = gx + c * mount.x_m - s * mount.y_m
        cam_y = gy + s * mount.x_m + c * mount.y_m
        rows, cols, layers = self._marked_in(self._window((cam_x, cam_y), image.range_max_m), (0, p.layers))
        if len(rows) == 0:
            return np.zeros(0, dtype=np.int32)
        w = self.shape[1]
        # voxel centres: grid frame → base frame → optical frame
        ex = (cols + 0.5) * res - gx
        ey = (rows + 0.5) * res - gy
        base = np.stack([c * ex + s * ey - mount.x_m, -s * ex + c * ey - mount.y_m,
                         p.floor_margin_m + (layers + 0.5) * p.z_resolution_m - mount.z_m], axis=1)
        optical = base @ self._rotation(image)  # row vectors: (R^T v)^T = v^T R
        z = optical[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.rint(image.fx * optical[:, 0] / z + image.cx)
            v = np.rint(image.fy * optical[:, 1] / z + image.cy)
        seen = (z > 0) & (u >= 0) & (u < image.width) & (v >= 0) & (v < image.height)
        measured = np.zeros(len(z), dtype=np.float64)
        measured[seen] = image.depth_m[v[seen].astype(np.intp), u[seen].astype(np.intp)]
        valid = (measured >= image.range_min_m) & (measured <= image.range_max_m)
        through = seen & valid & (measured > z + p.clear_margin_m)
        flat = ((rows[through] * w + cols[through]) * p.layers + layers[through]).astype(np.int32)
        self._voxels_flat[flat] = False
        return flat

    def _clear_by_lidar(self, scan: LaserScan, frame: tuple[float, float, float, float]) -> NDArray[np.int32]:
        """Empty the marked voxels of the lidar's band (`VoxelLayerParams.lidar_layers`) in cells a beam of
        ``scan`` passes through; returns their flat indices. From the voxels' side, as `_clear`: each one's cell
        centre gives a bearing from the lidar, the beam nearest that bearing a range, and a valid return farther
        than the centre by ``clear_margin_m`` means the beam crossed the cell at the lidar's plane."""
        p = self.params
        first, end = p.lidar_layers
        empty = np.zeros(0, dtype=np.int32)
        ranges = np.asarray(scan.ranges_m, dtype=np.float64)
        if end <= first or len(ranges) == 0 or scan.angle_increment_rad <= 0:
            return empty
        res = self.resolution_m
        c, s, gx, gy = frame
        mount = scan.sensor_pose
        lx = gx + c * mount.x_m - s * mount.y_m
        ly = gy + s * mount.x_m + c * mount.y_m
        rows, cols, layers = self._marked_in(self._window((lx, ly), scan.range_max_m), (first, end))
        if len(rows) == 0:
            return empty
        w = self.shape[1]
        ex = (cols + 0.5) * res - lx
        ey = (rows + 0.5) * res - ly
        dist = np.hypot(ex, ey)
        # the bearing in the lidar's frame: grid-frame bearing less the robot's yaw and the lidar's own
        bearing = np.arctan2(ey, ex) - math.atan2(s, c) - mount.yaw_rad
        offset = np.mod(bearing - scan.angle_min_rad, 2 * math.pi)
        beam = np.rint(offset / scan.angle_increment_rad).astype(np.intp)
        beam[beam == round(2 * math.pi / scan.angle_increment_rad)] = 0  # a full turn is the first beam again
        on = beam < len(ranges)
        measured = np.full(len(dist), np.nan)
        measured[on] = ranges[beam[on]]
        with np.errstate(invalid="ignore"):
            valid = (measured >= scan.range_min_m) & (measured <= scan.range_max_m)
            through = valid & (measured > dist + p.clear_margin_m)
        flat = ((rows[through] * w + cols[through]) * p.layers + layers[through]).astype(np.int32)
        self._voxels_flat[flat] = False
        return flat

    def _window(self, centre: tuple[float, float], reach_m: float) -> tuple[int, int, int, int]:
        """The cells (rows rs:re, columns cs:ce, clipped to the grid; empty off it) within ``reach_m`` of a sensor at
        ``centre`` (grid-frame metres), a cell to spare."""
        res = self.resolution_m
        reach = math.ceil(reach_m / res) + 1
        h, w = self.shape
        r0, c0 = math.floor(centre[1] / res), math.floor(centre[0] / res)
        return max(r0 - reach, 0), min(r0 + reach + 1, h), max(c0 - reach, 0), min(c0 + reach + 1, w)

    def _marked_in(self, box: tuple[int, int, int, int], band: tuple[int, int]
                   ) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
        """Row, column and layer of every marked voxel of the cells ``box`` (rows rs:re, columns cs:ce) and the
        layers ``band``, in C order (what ``np.nonzero`` of that block gives). Only the marked columns are looked
        into: a column holds a marked voxel only if `columns` says so (between updates they agree; during one,
        clearing may leave a column up whose voxels are gone), and most of a 6 m window is empty."""
        rs, re, cs, ce = box
        first, end = band
        # the window's rows that hold a marked column first (one quick pass), then those rows only: np.nonzero of a
        # strided window walks every cell of it, three times slower on a 6 m window
        window = self.columns[rs:re, cs:ce]
        marked_rows = np.flatnonzero(window.any(axis=1))
        which_row, col_cols = np.nonzero(window[marked_rows])
        col_rows = marked_rows[which_row] + rs
        col_cols += cs
        which, layers = np.nonzero(self.voxels[col_rows, col_cols, first:end])
        return col_rows[which], col_cols[which], layers + first

    def _rotation(self, image: DepthImage) -> NDArray[np.float64]:
        """The camera's optical → base rotation (cached per mount)."""
        if self._mount is not image.mount and self._mount != image.mount:
            self._mount, self._mount_rotation = image.mount, mount_rotation(image.mount)
        return self._mount_rotation

    def _mark(self, image: DepthImage, frame: tuple[float, float, float, float], scan: LaserScan | None
              ) -> NDArray[np.int32]:
        """Set the voxels that hold at least ``min_points`` of the frame's points within ``mark_range_m``, away from
        the map's and the lidar's obstacles; returns their flat indices."""
        p = self.params
        rays, depth = self._projector.rays(image), self._projector.strided(image)
        if rays.shape[0] != depth.shape[0]:  # the compiled loop reads both without bounds checks
            raise NavigationError(f"voxel layer: {depth.shape[0]} depths for {rays.shape[0]} pixel rays")
        c, s, gx, gy = frame
        found = np.empty(len(depth), dtype=np.int32)
        count = _marks(
            (depth, np.float32(image.range_min_m), np.float32(image.range_max_m)), (rays, self._projector.origin),
            (np.float32(c), np.float32(s), np.float32(gx), np.float32(gy)),
            (np.float32(1.0 / self.resolution_m), np.float32(p.floor_margin_m), np.float32(1.0 / p.z_resolution_m),
             np.float32(p.mark_range_m ** 2)),
            (self.shape[0], self.shape[1], p.layers),
            (self._static_flat, np.float32(self._min_match), np.float32(p.wall_match_m),
             np.float32(p.wall_match_per_m)), found)
        flat = found[:count]
        if scan is not None and len(flat):
            flat = flat[~self._lidar_sees(flat // p.layers, scan, frame)]
        if len(flat) and p.min_points > 1:
            voxels, counts = np.unique(flat, return_counts=True)
            flat = voxels[counts >= p.min_points]
        self._voxels_flat[flat] = True
        return flat

    def _lidar_sees(self, cells: NDArray[np.int32], scan: LaserScan, frame: tuple[float, float, float, float]
                    ) -> NDArray[np.bool_]:
        """Which of ``cells`` (flat cell indices) lie within ``lidar_margin_m`` of one of the scan's returns: a
        distance transform over the box the cells span, from the returns that fall in it."""
        ranges = np.asarray(scan.ranges_m, dtype=np.float64)
        ok = np.isfinite(ranges) & (ranges >= scan.range_min_m) & (ranges <= scan.range_max_m)
        if not ok.any():
            return np.zeros(len(cells), dtype=bool)
        mount = scan.sensor_pose
        angles = mount.yaw_rad + scan.angles_rad[ok]
        returns = np.zeros((int(ok.sum()), 3), dtype=np.float32)
        returns[:, 0] = mount.x_m + ranges[ok] * np.cos(angles)
        returns[:, 1] = mount.y_m + ranges[ok] * np.sin(angles)
        returns[:, 2] = self.params.floor_margin_m  # any height inside the grid: only the cell matters here
        hit, inside = self._flat(returns, frame)
        hit_cells = hit[inside] // self.params.layers
        w = self.shape[1]
        margin = math.ceil(self.params.lidar_margin_m / self.resolution_m)
        rows, cols = cells // w, cells % w
        r0, c0 = int(rows.min()) - margin, int(cols.min()) - margin
        r1, c1 = int(rows.max()) + margin + 1, int(cols.max()) + margin + 1
        hr, hc = hit_cells // w, hit_cells % w
        keep = (hr >= r0) & (hr < r1) & (hc >= c0) & (hc < c1)
        if not keep.any():
            return np.zeros(len(cells), dtype=bool)
        seen = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        seen[hr[keep] - r0, hc[keep] - c0] = True
        distance = ndimage.distance_transform_edt(~seen) * self.resolution_m
        near: NDArray[np.bool_] = distance[rows - r0, cols - c0] <= self.params.lidar_margin_m
        return near

    def _decay(self, now: float) -> NDArray[np.int32]:
        """Forget the columns not marked for ``decay_s``; returns the flat index of their first voxel each."""
        old = np.flatnonzero(self.columns.reshape(-1) & (self._seen_t.reshape(-1) < now - self.params.decay_s))
        if len(old) == 0:
            return np.zeros(0, dtype=np.int32)
        w = self.shape[1]
        self.voxels[old // w, old % w, :] = False
        return (old * self.params.layers).astype(np.int32)

    def _project(self, flat: NDArray[np.int32]) -> None:
        """Recompute the columns inside the box the touched voxels span."""
        if len(flat) == 0:
            return
        cell = flat // self.params.layers
        w = self.shape[1]
        lo, hi = int(cell.min()), int(cell.max())
        r0, r1 = lo // w, hi // w + 1
        cols = cell % w
        c0, c1 = int(cols.min()), int(cols.max()) + 1
        self.columns[r0:r1, c0:c1] = self.voxels[r0:r1, c0:c1].any(axis=2)

    # -- for the motion pipeline -----------------------------------------------------------------------------
    def clearance(self, pose: Pose2D) -> Clearance:
        """Nearest marked cell ahead (within ±60° of the heading), behind and beside the robot at ``pose``,
        metres from the base origin to the cell's near side; inf where there is none within ``zone_radius_m``.

        The same directions as the lidar's `Clearance` (`atemr.skills.hexpattern`), so the speed ramp's slow
        and stop zones treat a table top the camera saw like a wall the lidar sees."""
        res = self.resolution_m
        reach = math.ceil(self.params.zone_radius_m / res) + 1
        c, s, gx, gy = self._grid_frame(pose)
        r0, c0 = math.floor(gy / res), math.floor(gx / res)
        h, w = self.shape
        rs, re = max(r0 - reach, 0), min(r0 + reach + 1, h)
        cs, ce = max(c0 - reach, 0), min(c0 + reach + 1, w)
        if rs >= re or cs >= ce:
            return Clearance()
        rows, cols = np.nonzero(self.columns[rs:re, cs:ce])
        if len(rows) == 0:
            return Clearance()
        ex = (cols + cs + 0.5) * res - gx
        ey = (rows + rs + 0.5) * res - gy
        ahead, left = c * ex + s * ey, -s * ex + c * ey
        dist = np.maximum(np.hypot(ahead, left) - res / 2, 0.0)
        bearing = np.abs(np.arctan2(left, ahead))
        out = []
        for mask in (bearing <= math.radians(60), bearing >= math.radians(120)):
            out.append(float(dist[mask].min()) if mask.any() else math.inf)
        side = (bearing > math.radians(60)) & (bearing < math.radians(120))
        return Clearance(out[0], out[1], float(dist[side].min()) if side.any() else math.inf)



@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) `_marks` when the first layer is built, not at
    the robot's first depth frame: the call has the argument types of `VoxelLayer._mark`'s (a test checks that a
    running robot has one compiled version of each loop)."""
    one, f32 = np.float32(1.0), np.ones(1, dtype=np.float32)
    _marks((f32, one, one), (np.ones((1, 3), dtype=np.float32), np.ones(3, dtype=np.float32)), (one, one, one, one),
           (one, one, one, one), (1, 1, 1), (f32, one, one, one), np.empty(1, dtype=np.int32))


#: Four float32 numbers (a frame, or the scales `_marks` takes).
Four32 = tuple[np.float32, np.float32, np.float32, np.float32]


@njit(cache=True, nogil=True)
def _marks(image: tuple[F32, np.float32, np.float32], camera: tuple[F32, F32], frame: Four32,  # noqa: PLR0917  one compiled loop
           scales: Four32, dims: tuple[int, int, int], walls: tuple[F32, np.float32, np.float32, np.float32],
           found: NDArray[np.int32]) -> int:  # pragma: no cover  compiled by numba
    """The flat voxel index of every valid pixel's point within the mark range, inside the grid and farther from
    the map's obstacles than its match distance, in pixel order, into ``found``; returns how many.

    ``image``: the (strided) depths and their valid range; ``camera``: each pixel's base-frame ray and the
    optical centre; ``frame``: base to grid frame (cos, sin, x, y); ``scales``: 1/cell, the floor margin,
    1/layer height and the squared mark range; ``dims``: rows, columns, layers; ``walls``: each cell's distance
    to the map's obstacles, and the match distance's floor, base and growth per metre. float32 throughout, as the
    numpy pipeline before it (its points, `VoxelLayer._flat`'s truncation, the match test)."""
    depth, lo, hi = image
    rays, origin = camera
    c, s, gx, gy = frame
    inv_res, floor, inv_z, near_sq = scales
    rows, cols, layers = dims
    static, least, base, per_m = walls
    one = np.float32(1.0)
    count = 0
    for i in range(depth.shape[0]):
        d = depth[i]
        if not (d >= lo and d <= hi):  # NaN compares False
            continue
        x = rays[i, 0] * d + origin[0]
        y = rays[i, 1] * d + origin[1]
        z = rays[i, 2] * d + origin[2]
        ex = x - origin[0]
        ey = y - origin[1]
        plan_sq = ex * ex + ey * ey
        if not plan_sq <= near_sq:
            continue
        col = np.int32((c * x - s * y + gx) * inv_res + one) - 1
        row = np.int32((s * x + c * y + gy) * inv_res + one) - 1
        layer = np.int32((z - floor) * inv_z + one) - 1
        if not (0 <= row < rows and 0 <= col < cols and 0 <= layer < layers):
            continue
        flat = (row * cols + col) * layers + layer
        if static[flat // layers] > max(least, base + per_m * np.sqrt(plan_sq)):
            found[count] = flat
            count += 1
    return count


__all__ = ["VoxelLayer", "VoxelLayerParams"]
