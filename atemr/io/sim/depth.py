"""A simulated depth camera like KAY's RealSense D415: depth of the same scene the lidar and the colour camera see.

Defaults follow the D415 at its 424 x 240 mode: about 65° x 40° field of view, 0.3 to 3 m, 10 frames per
second. Every pixel's ray (from `atemr.skills.depth_cloud.pixel_rays` and the mount, the very model the
obstacle layer reads the image back with) is intersected with everything, vectorised over pixels (the shapes'
tests are compiled loops over the pixels they span):

* the floor (z = 0) and the ceiling (at the wall height);
* the walls, extruded from the floor to the wall height: one 2-D grid cast per azimuth bin (twice as many
  bins as columns), and each pixel takes the horizontal distance of its bin, divided by how much of its ray
  is horizontal;
* every object as a 3-D box or a vertical cylinder from its ``clearance_m`` to its ``height_m`` (slab and
  quadratic tests), skipping those out of reach; people and pets as cylinders from the floor.

The image holds z-depth (along the optical axis), 0 where nothing is within range, like the SDK's. The noise
is a stereo camera's: its standard deviation grows with the square of the depth,
``sigma = subpixel · z² / (fx · baseline)`` (the D415: 55 mm baseline, about 0.08 px subpixel accuracy, so
4 mm at 1 m and 4 cm at 3 m), plus a small fraction of pixels without data. Seeded: the simulation's own
generator draws it, inside the compiled loop that finishes the image (`_finish`), as numpy's own draws would.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numba import float32, njit
from numpy.typing import NDArray

try:  # numba's own building blocks of its Generator support (numba 0.56 to 0.68 at least): see `_finish`
    from numba.np.random._constants import fi_float, ki_float, wi_float, ziggurat_nor_inv_r_f, ziggurat_nor_r_f
    from numba.np.random.generator_core import next_float, next_uint32
except ImportError as exc:  # pragma: no cover  only with a numba that moved them
    import numba

    raise ImportError(f"the simulated depth camera draws its noise with numba's numpy-random internals "
                      f"(numba.np.random.generator_core, ._constants), which numba {numba.__version__} does not "
                      f"have: install a numba between 0.60 and 0.68, or report it") from exc

from atemr.errors import ConfigError
from atemr.io.sim.movers import Movers
from atemr.io.sim.scene import Scene
from atemr.msgs import CameraMount, DepthImage, Pose2D
from atemr.skills.depth_cloud import mount_rotation, pixel_rays

F32 = NDArray[np.float32]
#: KAY's D415 on the mast under the tablet, 0.85 m up and 10 cm ahead of the axle, tilted 12° down (its view
#: spans 32° down to 8° up): it sees the floor from 1.4 m ahead, a shoe from 1.2 m, a table top at 0.72 m from
#: 0.3 m, and a shelf at the tablet's height; what it saw it remembers when it is too close to see.
D415_MOUNT = CameraMount(x_m=0.10, y_m=0.0, z_m=0.85, pitch_rad=math.radians(12.0))


@dataclass(frozen=True)
class DepthCameraParams:
    """The depth camera's geometry, range and noise (defaults: a D415 at 424 x 240)."""

    width: int = 424
    height: int = 240
    hfov_deg: float = 65.0
    vfov_deg: float = 40.0
    range_min_m: float = 0.3
    range_max_m: float = 3.0
    baseline_m: float = 0.055
    subpixel_px: float = 0.08
    dropout_prob: float = 0.002
    mount: CameraMount = field(default_factory=lambda: D415_MOUNT)

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 2048 and 16 <= self.height <= 2048):
            raise ConfigError(f"image size must be within 16..2048, got {self.width}x{self.height}", path="depth")
        if not (10.0 <= self.hfov_deg <= 170.0 and 10.0 <= self.vfov_deg <= 170.0):
            raise ConfigError("fields of view must be within 10..170 degrees", path="depth")
        if not 0 < self.range_min_m < self.range_max_m <= 50:
            raise ConfigError(f"need 0 < range_min_m < range_max_m <= 50, got {self.range_min_m}, "
                              f"{self.range_max_m}", path="depth")
        if not (0 <= self.subpixel_px < 5 and 0 <= self.dropout_prob < 1 and self.baseline_m > 0):
            raise ConfigError("subpixel_px within [0, 5), dropout_prob within [0, 1), baseline_m > 0", path="depth")

    @property
    def fx(self) -> float:
        return (self.width / 2) / math.tan(math.radians(self.hfov_deg) / 2)

    @property
    def fy(self) -> float:
        return (self.height / 2) / math.tan(math.radians(self.vfov_deg) / 2)

    @property
    def cx(self) -> float:
        return self.width / 2 - 0.5

    @property
    def cy(self) -> float:
        return self.height / 2 - 0.5

    @property
    def noise_per_m2(self) -> np.float32:
        """The depth noise's standard deviation at 1 m (`noise_std_m` is this times the depth squared)."""
        return np.float32(self.subpixel_px / (self.fx * self.baseline_m))

    def noise_std_m(self, depth_m: F32) -> F32:
        """Depth noise of a stereo camera: grows with the square of the depth."""
        out: F32 = self.noise_per_m2 * depth_m * depth_m
        return out


class DepthCamera:
    """Renders `DepthImage`s of the scene from a robot pose; ``rng`` draws the noise and the dropouts.

    The pixels are kept sorted by the azimuth of their rays, so an object is tested only against the slice of
    pixels whose azimuths its plan-view outline spans (a chair at the image's edge costs a tenth of the image).
    """

    def __init__(self, params: DepthCameraParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        p = params
        optical = pixel_rays((p.width, p.height), (p.fx, p.fy, p.cx, p.cy))
        norm = np.linalg.norm(optical, axis=1)
        base = (optical / norm[:, None]) @ mount_rotation(p.mount).T
        azimuth = np.arctan2(base[:, 1], base[:, 0])
        bins = 2 * p.width
        lo, hi = float(azimuth.min()), float(azimuth.max())
        step = max(hi - lo, 1e-9) / (bins - 1)
        pixel_bin = np.clip(np.rint((azimuth - lo) / step), 0, bins - 1).astype(np.intp)
        order = np.argsort(pixel_bin, kind="stable")
        #: Pixel index (row-major) of each sorted position, and where each azimuth bin's pixels start.
        self._order = order
        #: Where each pixel (row-major) sits in the sorted order: the image is one gather from the sorted depths.
        self._unsort = np.argsort(order).astype(np.intp)
        self._bin_start = np.searchsorted(pixel_bin[order], np.arange(bins + 1))
        self._bin = pixel_bin[order]
        self._lo, self._step, self._bins = lo, step, bins
        #: Azimuths (base frame) of the wall casts.
        self._bin_azimuth: NDArray[np.float64] = lo + step * np.arange(bins, dtype=np.float64)
        base = base[order]
        self._dir = base.astype(np.float32)  # unit rays in the base frame, sorted, (N, 3)
        self._inv_horizontal = (1.0 / np.maximum(np.hypot(base[:, 0], base[:, 1]), 1e-6)).astype(np.float32)
        #: z-depth per metre along each (unit) ray.
        self._depth_per_t = (1.0 / norm[order]).astype(np.float32)
        # Floor and ceiling do not turn with the robot: where each ray meets them is fixed by the mount.
        dz = self._dir[:, 2]
        self._dz_safe = np.where(np.abs(dz) < 1e-6, np.float32(1e-6), dz).astype(np.float32)
        self._inv_dz = (1.0 / self._dz_safe).astype(np.float32)
        self._floor_t = np.where(dz < 0, -p.mount.z_m * self._inv_dz, np.inf).astype(np.float32)
        self._ceiling_t: dict[float, F32] = {}
        self._reach = math.hypot(p.range_max_m, p.mount.z_m) + 0.5
        #: What `_finish` needs of the noise and the range: float32, as numpy compares a float32 image with a
        #: Python float; and whether the noise and the dropouts are drawn at all.
        self._noise = (np.array([p.noise_per_m2, p.range_min_m, p.range_max_m, p.dropout_prob], dtype=np.float32),
                       p.subpixel_px != 0, p.dropout_prob != 0)
        #: The last `_static_view`: (its `Scene.view_key`, the distances, the walls by bin).
        self._static: tuple[tuple[float, float, float, object], F32, NDArray[np.float64]] | None = None
        load_compiled()

    def render(self, t: float, pose: Pose2D, scene: Scene, movers: Movers | None = None) -> DepthImage:
        """The depth image seen from the robot at ``pose`` (true pose: the simulator's)."""
        p = self.params
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        m = p.mount
        origin = (pose.x_m + c * m.x_m - s * m.y_m, pose.y_m + s * m.x_m + c * m.y_m, m.z_m)
        static, flat = self._static_view(pose, scene, origin, (c, s))
        t_hit = static.copy()
        # People and pets in view and not behind the walls of every bin they span, as the furniture.
        shapes: list[tuple[tuple[int, int], str, tuple[float, ...], tuple[float, float]]] = []
        for mover in movers.items if movers is not None else ():
            circle = (mover.x_m, mover.y_m, mover.spec.radius_m)
            span = self._slice(_outline_azimuths("circle", circle, origin[0], origin[1]), pose.yaw_rad, flat)
            if span is not None:
                shapes.append((span, "circle", circle, (0.0, mover.spec.height_m)))
        if shapes:
            self._hit_shapes(t_hit, shapes, origin, (c, s))
        return DepthImage(t, self._image(t_hit).reshape(p.height, p.width), p.fx, p.fy, p.cx, p.cy, p.range_min_m,
                          p.range_max_m, m)

    def _static_view(self, pose: Pose2D, scene: Scene, origin: tuple[float, float, float],
                     turn: tuple[float, float]) -> tuple[F32, NDArray[np.float64]]:
        """The sorted pixels' hit distances on what does not move (floor, ceiling, walls, furniture; read-only),
        and the plan distance to the wall in each azimuth bin; the last ones are kept for their `Scene.view_key`.
        Each shape lowers a pixel's distance to the nearest of them, so the furniture taken first and the people
        after give the same distances as all of them at once."""
        key = scene.view_key(pose)
        kept = self._static
        if kept is not None and kept[0] == key:
            return kept[1], kept[2]
        ox, oy = origin[0], origin[1]
        t_hit = np.minimum(self._floor_t, self._ceiling(scene.world.wall_height_m))
        # Walls: one grid cast per azimuth bin, in the grid frame.
        gx, gy, gyaw = scene.to_grid_frame(ox, oy, pose.yaw_rad)
        flat = scene.walls_caster.cast((gx, gy), gyaw + self._bin_azimuth, self._reach).distance_m
        np.minimum(t_hit, flat.astype(np.float32)[self._bin] * self._inv_horizontal, out=t_hit)
        # Furniture in view and not behind the walls of every bin it spans (a ray meets it no nearer, in plan,
        # than its outline's nearest point: the wall it meets first hides it). In a flat most of the furniture
        # is in other rooms.
        shapes: list[tuple[tuple[int, int], str, tuple[float, ...], tuple[float, float]]] = []
        for item in scene.objects.values():
            span = self._slice(_outline_azimuths(item.shape, item.params, ox, oy), pose.yaw_rad, flat)
            if span is not None:
                shapes.append((span, item.shape, item.params, (item.clearance_m, item.height_m)))
        if shapes:
            self._hit_shapes(t_hit, shapes, origin, turn)
        t_hit.setflags(write=False)
        self._static = (key, t_hit, flat)
        return t_hit, flat

    def _image(self, t_hit: F32) -> F32:
        """The image's pixels (row-major) from the sorted pixels' hit distances: z-depth with noise, 0 out of range."""
        depth = np.empty(len(t_hit), dtype=np.float32)
        _finish(t_hit, (self._depth_per_t, self._unsort), self.rng, self._noise, depth)
        return depth

    def _ceiling(self, height_m: float) -> F32:
        t = self._ceiling_t.get(height_m)
        if t is None:
            dz = self._dir[:, 2]
            t = np.where(dz > 0, (height_m - self.params.mount.z_m) * self._inv_dz, np.inf).astype(np.float32)
            self._ceiling_t[height_m] = t
        return t

    def _hit_shapes(self, t_hit: F32, shapes: list[tuple[tuple[int, int], str, tuple[float, ...], tuple[float, float]]],
                    origin: tuple[float, float, float], turn: tuple[float, float]) -> None:
        """Lower ``t_hit`` (sorted pixels) to each shape's hits: (pixel span, "box" or "circle", its plan
        outline, (bottom, top) heights). The rays are turned to the world and inverted only over the pixels
        the shapes span, once for all of them."""
        lo, hi = min(a for (a, _), *_ in shapes), max(b for (_, b), *_ in shapes)
        c, s = np.float32(turn[0]), np.float32(turn[1])
        d = self._dir[lo:hi]
        dx = c * d[:, 0] - s * d[:, 1]
        dy = s * d[:, 0] + c * d[:, 1]
        dz = self._dz_safe[lo:hi]
        inv: tuple[F32, F32, F32] | None = None
        for (a, b), shape, outline, (bottom, top) in shapes:
            i, j = a - lo, b - lo
            if shape == "box":
                if inv is None:  # inverse directions once per frame for every box's slab test
                    inv = (_inverse(dx), _inverse(dy), self._inv_dz[lo:hi])
                x0, y0, x1, y1 = outline
                _box_hits(_slabs(origin, (x0, y0, bottom), (x1, y1, top)), (inv[0][i:j], inv[1][i:j], inv[2][i:j]),
                          t_hit[a:b])
            else:
                _cylinder_hits(_cylinder(origin, outline, (bottom, top)), (dx[i:j], dy[i:j], dz[i:j]), t_hit[a:b])

    def _slice(self, outline: tuple[float, float, float] | None, yaw: float,
               walls: NDArray[np.float64] | None = None) -> tuple[int, int] | None:
        """The sorted pixels whose azimuths an outline spans (None: out of view, out of reach, or behind the
        ``walls``, the plan distance to the wall in each azimuth bin); an outline the camera stands inside
        (None from `_outline_azimuths`) spans every pixel."""
        if outline is None:
            return 0, len(self._bin)
        centre, half, gap = outline
        if gap > self._reach:
            return None
        rel = math.atan2(math.sin(centre - yaw), math.cos(centre - yaw))
        b0 = math.floor((rel - half - self._lo) / self._step) - 1
        b1 = math.ceil((rel + half - self._lo) / self._step) + 1
        if b1 < 0 or b0 > self._bins - 1:
            return None
        b0, b1 = max(b0, 0), min(b1, self._bins - 1)
        if walls is not None and gap >= walls[b0:b1 + 1].max():
            return None
        a = int(self._bin_start[b0])
        b = int(self._bin_start[b1 + 1])
        return (a, b) if b > a else None


def _inverse(d: F32) -> F32:
    """1 / d with no component exactly 0 (a ray parallel to a slab then meets it only at infinity)."""
    tiny = np.abs(d) < 1e-6
    if tiny.any():  # rare: only a ray (almost) along an axis
        d = np.where(tiny, np.float32(1e-6), d)
    out: F32 = np.divide(np.float32(1.0), d, dtype=np.float32)
    return out


def _outline_azimuths(shape: str, params: tuple[float, ...], ox: float, oy: float
                      ) -> tuple[float, float, float] | None:
    """(world azimuth of the outline's middle, half its angular width, nearest plan distance) as seen from
    (ox, oy); None when (ox, oy) is inside it."""
    if shape == "box":
        x0, y0, x1, y1 = params
        if x0 <= ox <= x1 and y0 <= oy <= y1:
            return None
        gap = math.hypot(max(x0 - ox, 0.0, ox - x1), max(y0 - oy, 0.0, oy - y1))
        centre = math.atan2((y0 + y1) / 2 - oy, (x0 + x1) / 2 - ox)
        rel = [math.atan2(math.sin(a - centre), math.cos(a - centre))
               for a in (math.atan2(y - oy, x - ox) for x in (x0, x1) for y in (y0, y1))]
        lo, hi = min(rel), max(rel)
        return centre + (lo + hi) / 2, (hi - lo) / 2, gap
    cx, cy, r = params
    dist = math.hypot(cx - ox, cy - oy)
    if dist <= r:
        return None
    return math.atan2(cy - oy, cx - ox), math.asin(r / dist), dist - r


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) the shape tests and the image's finish when
    the first camera is built, not at the first frame with a chair in it: the calls have the argument types of
    `_hit_shapes`'s and `_image`'s (a test checks that a running robot has one compiled version of each loop)."""
    rays = (np.ones(1, dtype=np.float32), np.ones(1, dtype=np.float32), np.ones(1, dtype=np.float32))
    _box_hits(np.ones(6, dtype=np.float32), rays, np.ones(1, dtype=np.float32))
    _cylinder_hits(np.ones(7, dtype=np.float32), rays, np.ones(1, dtype=np.float32))
    _finish(np.ones(1, dtype=np.float32), (np.ones(1, dtype=np.float32), np.zeros(1, dtype=np.intp)),
            np.random.default_rng(0), (np.ones(4, dtype=np.float32), True, True), np.empty(1, dtype=np.float32))


@njit(cache=True, nogil=True, error_model="numpy")
def _finish(t_hit: F32, sorted_to_image: tuple[F32, NDArray[np.intp]], rng: np.random.Generator,
            noise: tuple[F32, bool, bool], depth: F32) -> None:  # pragma: no cover  compiled by numba
    """The image from the sorted pixels' hit distances: z-depth (``t_hit`` capped at 1 km, as nothing hit, times
    each ray's depth per metre), in image order, with the stereo noise drawn from ``rng``, and 0 out of range or
    dropped. The numbers and the draws of the numpy it replaces, in its order: every pixel's normal first, then
    every pixel's uniform (`_standard_normal_f`, `_uniform_f`)."""
    per_t, unsort = sorted_to_image
    consts, noisy, drops = noise
    k, lo, hi, drop = consts[0], consts[1], consts[2], consts[3]
    cap = np.float32(1e3)
    bitgen = rng.bit_generator
    for i in range(depth.shape[0]):
        j = unsort[i]
        t = t_hit[j]
        d = (cap if t > cap else t) * per_t[j]  # np.minimum: a NaN stays NaN
        if noisy:
            d = d + k * d * d * _standard_normal_f(bitgen)
        depth[i] = d
    for i in range(depth.shape[0]):
        d = depth[i]
        out = not (d >= lo and d <= hi)
        if drops and _uniform_f(bitgen) < drop:  # drawn for every pixel, in range or not
            out = True
        if out:
            depth[i] = 0.0


# -- numpy's float32 draws, one at a time inside `_finish` ---------------------------------------------------------
#
# The noise is a normal and a uniform for each of 100,000 pixels, ten times a second: drawn by
# ``Generator.standard_normal(dtype=float32)`` and ``Generator.random(dtype=float32)`` and applied in numpy passes,
# it was most of a frame. Drawn inside the loop that uses them, the normals cost a third of what numpy's did, and the
# passes are one: the whole finish takes half the time.
# They must stay numpy's numbers, bit for bit and in numpy's order: every seeded run depends on them. These are
# numpy's own algorithms (``random_standard_normal_f``, its float32 ziggurat, and ``next_float``), on numba's access
# to the generator's bit generator (``next_uint32`` advances the numpy object's own state) and numba's copy of
# numpy's ziggurat tables. Numba's own ``Generator.standard_normal`` is not used: it compares its wedge test in
# float32 where numpy compares in float64, so one draw in a few million differs and the stream drifts from there
# on. A test holds these to numpy over millions of draws, tails and wedges included. They live
# in this module because numba's cache of `_finish` is checked against this file alone.

@njit(cache=True, nogil=True)
def _standard_normal_f(bitgen):  # type: ignore[no-untyped-def]  # pragma: no cover  compiled by numba
    """One draw of ``Generator.standard_normal(dtype=np.float32)`` from ``bitgen`` (a jitted function's
    ``rng.bit_generator``): numpy's float32 ziggurat. The 99.3 % of draws that land in a box are answered here,
    the rest in `_beyond_the_box` (kept apart, this path is three times faster than with the loop inline)."""
    r = next_uint32(bitgen)
    idx = r & 0xFF
    rabs = (r >> 9) & 0x0007FFFFF
    if rabs < ki_float[idx]:
        x = float32(float32(rabs) * wi_float[idx])
        return -x if (r >> 8) & 0x1 else x
    return _beyond_the_box(bitgen, r)


@njit(cache=True, nogil=True)
def _beyond_the_box(bitgen, r):  # type: ignore[no-untyped-def]  # pragma: no cover  compiled by numba
    """numpy's ziggurat loop from a draw ``r`` outside its box: the tail beyond the base strip, or a wedge whose
    test is compared in float64 as numpy's C does; a rejected draw starts over with a new one."""
    while True:
        idx = r & 0xFF
        rabs = (r >> 9) & 0x0007FFFFF
        x = float32(float32(rabs) * wi_float[idx])
        if (r >> 8) & 0x1:
            x = -x
        if rabs < ki_float[idx]:
            return x
        if idx == 0:
            while True:
                xx = float32(-ziggurat_nor_inv_r_f * np.log1p(float32(-next_float(bitgen))))
                yy = float32(-np.log1p(float32(-next_float(bitgen))))
                if float32(yy + yy) > float32(xx * xx):
                    if (rabs >> 8) & 0x1:
                        return -float32(ziggurat_nor_r_f + xx)
                    return float32(ziggurat_nor_r_f + xx)
        wedge = float32(float32((fi_float[idx - 1] - fi_float[idx]) * next_float(bitgen)) + fi_float[idx])
        if wedge < np.exp(-0.5 * float(x) * float(x)):
            return x
        r = next_uint32(bitgen)


@njit(cache=True, nogil=True)
def _uniform_f(bitgen):  # type: ignore[no-untyped-def]  # pragma: no cover  compiled by numba
    """One draw of ``Generator.random(dtype=np.float32)`` from ``bitgen``: in [0, 1), 24 random bits."""
    return next_float(bitgen)


def _slabs(origin: tuple[float, float, float], lo: tuple[float, float, float], hi: tuple[float, float, float]
           ) -> F32:
    """A box's near and far faces on each axis, less the ray origin, as float32 (x lo, y lo, z lo, x hi, ...)."""
    return np.array([np.float32(a - o) for a, o in zip(lo, origin, strict=True)]
                    + [np.float32(b - o) for b, o in zip(hi, origin, strict=True)], dtype=np.float32)


@njit(cache=True, nogil=True, error_model="numpy")
def _box_hits(slabs: F32, inv: tuple[F32, F32, F32], t_hit: F32) -> None:  # pragma: no cover  compiled by numba
    """Lower ``t_hit`` to the distance along each ray (given by its inverse direction, no component 0) to an
    axis-aligned box (slab test; ``slabs`` from `_slabs`) where it meets the box ahead of the camera."""
    for q in range(t_hit.shape[0]):
        enter = -np.inf
        leave = np.inf
        for axis in range(3):
            inv_d = inv[0][q] if axis == 0 else (inv[1][q] if axis == 1 else inv[2][q])
            t1 = slabs[axis] * inv_d
            t2 = slabs[axis + 3] * inv_d
            enter = max(enter, min(t1, t2))
            leave = min(leave, max(t1, t2))
        if leave >= enter > 0:
            t_hit[q] = min(t_hit[q], enter)


def _cylinder(origin: tuple[float, float, float], circle: tuple[float, ...], heights: tuple[float, float]) -> F32:
    """What `_cylinder_hits` needs of a vertical cylinder seen from ``origin``, as float32: the origin less the
    centre (x, y), the quadratic's constant term, r², the origin's height, the bottom and the top."""
    ox, oy, oz = origin
    cx, cy, r = circle
    fx, fy = np.float32(ox - cx), np.float32(oy - cy)
    c = np.float32(fx * fx + fy * fy - r * r)
    return np.array([fx, fy, c, r * r, oz, heights[0], heights[1]], dtype=np.float32)


@njit(cache=True, nogil=True, error_model="numpy")
def _cylinder_hits(cylinder: F32, rays: tuple[F32, F32, F32],
                   t_hit: F32) -> None:  # pragma: no cover  compiled by numba
    """Lower ``t_hit`` to the distance along each ray to a vertical cylinder (``cylinder`` from `_cylinder`), its
    side or its caps (the top seen from above, the bottom from below)."""
    fx, fy, c, r_sq = cylinder[0], cylinder[1], cylinder[2], cylinder[3]
    oz, bottom, top = cylinder[4], cylinder[5], cylinder[6]
    dxs, dys, dzs = rays
    zero = np.float32(0.0)
    for q in range(t_hit.shape[0]):
        dx, dy, dz = dxs[q], dys[q], dzs[q]
        a = dx * dx + dy * dy
        b = fx * dx + fy * dy
        disc = b * b - a * c
        t_side = (-b - np.sqrt(max(disc, zero))) / a
        z = oz + t_side * dz
        hit = t_side if disc >= 0 and t_side >= 0 and z >= bottom and z <= top else np.float32(np.inf)
        t_cap = ((top if dz < 0 else bottom) - oz) / dz
        hx = fx + t_cap * dx
        hy = fy + t_cap * dy
        if t_cap >= 0 and hx * hx + hy * hy <= r_sq and dz != 0:
            hit = min(hit, t_cap)
        t_hit[q] = min(t_hit[q], hit)

__all__ = ["D415_MOUNT", "DepthCamera", "DepthCameraParams"]
