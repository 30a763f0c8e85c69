"""The HEX-PATTERN generator (thesis 3.4.2): a 360-beam scan reduced to six sector values.

A scan is transformed to the base frame (x forward, y left), invalid returns are dropped, and the points
are split by bearing into six 60° sectors named Front-Right (FR), Front-Left (FL), Left-Center (LC),
Rear-Left (RL), Rear-Right (RR) and Right-Center (RC). Each sector is reduced to the mean range of its
valid returns within the radius of interest (1.2 m for the fuzzy engines) and, for the speed ramp's
safety zones, to its nearest return.

Sector layouts — the thesis draws them in figures 3.26 (HEX-PATTERN) and 3.27 (HEX-PATTERN-90, "a 90
degree rotated version of the former and ... the pattern type around which the Fuzzy Inference Engine
is built"), which the text copy lacks; so the angles below are this project's reading of the text:

* HEX-90 (``hex90``) is the layout whose names are the robot's directions, because the fuzzy rules are
  written in those names ("steer away from what is Front-Left"). Two front sectors meet on the x axis,
  one sector is centred on each side (Left-*Center*, Right-*Center*), two rear sectors meet on the -x
  axis: boundaries at 0°, ±60°, ±120°, 180°.
* HEX (``hex``) is HEX-90 turned back by 90° (HEX-90 = HEX rotated +90°, as the thesis says), each name
  kept on its hexagon face. Its boundaries fall at ±30°, ±90°, ±150°: one face straight ahead, one
  straight behind, two on each side. In HEX the names label faces, not directions: the face straight
  ahead is called LC. It is kept for consumers that want a sector centred on the heading.

The speed ramp's zones use HEX-90 by direction (`HexSectors.nearest_by_direction`): its front pair
FL+FR covers bearings within ±60°, which is the path a round footprint sweeps when it drives straight,
seen from the stop distance (KAY's 0.25 m footprint radius at 0.28 m: asin(0.25/0.28) ≈ 63°); an
obstacle beside the base (LC, RC) is passed, not hit.

The layouts are data in `HEX_LAYOUTS` (a registry), so a third layout is one entry, and the drawings in
docs/navigation.md#hex-layouts come from the same table (`ascii_drawing`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit
from numpy.typing import NDArray

from atemr.errors import ConfigError, ProtocolError
from atemr.msgs import FloatArray, LaserScan, Pose2D
from atemr.registry import Registry

#: The six sector names in the order every result array uses (the order of thesis 3.4.2's sentence).
SECTORS: tuple[str, ...] = ("FR", "FL", "LC", "RL", "RR", "RC")

#: Radius of interest of the fuzzy engines (thesis 5.2: "configured to work with obstacle distances of 1.2 m").
DEFAULT_RADIUS_M = 1.2


@dataclass(frozen=True)
class HexLayout:
    """Six sectors around the base: ``starts_deg[i]`` is where ``order[i]`` begins, counter-clockwise.

    Sector ``order[i]`` spans ``[starts_deg[i], starts_deg[i + 1])`` (the last one wraps round to the
    first); angles are degrees in the base frame, 0° straight ahead, counter-clockwise positive.
    """

    name: str
    order: tuple[str, ...]
    starts_deg: tuple[float, ...]
    source: str

    def __post_init__(self) -> None:
        if sorted(self.order) != sorted(SECTORS):
            raise ConfigError(f"layout {self.name}: sectors must be {', '.join(SECTORS)} once each, got {self.order}")
        steps = np.diff(np.asarray((*self.starts_deg, self.starts_deg[0] + 360.0)))
        if len(self.starts_deg) != len(self.order) or np.any(steps <= 0.0):
            raise ConfigError(f"layout {self.name}: starts must increase counter-clockwise and span 360°")

    def span_deg(self, sector: str) -> tuple[float, float]:
        """(start, end) of ``sector`` in degrees, end > start, end - start < 360."""
        i = self.order.index(sector)
        end = self.starts_deg[i + 1] if i + 1 < len(self.order) else self.starts_deg[0] + 360.0
        return self.starts_deg[i], end

    def centre_deg(self, sector: str) -> float:
        """The bisector of ``sector`` wrapped to (-180, 180]."""
        start, end = self.span_deg(sector)
        return _wrap_deg((start + end) / 2.0)

    def rotated(self, name: str, by_deg: float, source: str) -> HexLayout:
        """This layout turned counter-clockwise by ``by_deg``, each name kept on its face."""
        return HexLayout(name, self.order, tuple(s + by_deg for s in self.starts_deg), source)


def _wrap_deg(a: float) -> float:
    w = math.fmod(a + 180.0, 360.0)
    return (w + 360.0 if w <= 0.0 else w) - 180.0


HEX_LAYOUTS: Registry[HexLayout] = Registry("hex_layout")

HEX90 = HexLayout(
    "hex90",
    order=("FL", "LC", "RL", "RR", "RC", "FR"),
    starts_deg=(0.0, 60.0, 120.0, 180.0, 240.0, 300.0),
    source="thesis fig. 3.27 (missing from the text copy); names read as directions: FL/FR meet on the x axis, "
    "LC/RC centred on ±90°, RL/RR meet behind",
)
HEX = HEX90.rotated(
    "hex",
    -90.0,
    source="thesis fig. 3.26 (missing): HEX-90 is 'a 90 degree rotated version' of HEX, so HEX = HEX-90 turned "
    "back 90°; the ±90° line splits it into front and rear halves",
)
HEX_LAYOUTS.add(HEX.name, HEX)
HEX_LAYOUTS.add(HEX90.name, HEX90)


@dataclass(frozen=True)
class HexSectors:
    """One scan reduced to six sectors; arrays are in `SECTORS` order (FR, FL, LC, RL, RR, RC).

    ``mean_m`` is the thesis's sector value: the mean range of valid returns within ``radius_m``; a
    sector with none reads ``radius_m`` (the farthest distance the engines consider, i.e. clear).
    ``nearest_m`` is the closest valid return in the sector at any range (inf when none): the safety
    zones use it, because the mean over a 60° sector of a flat wall at distance d is about 1.26·d and
    would let the base come a fifth closer than the stop distance. ``count`` is the number of returns
    averaged. Ranges are measured from the base origin.
    """

    layout: HexLayout
    radius_m: float
    mean_m: FloatArray
    nearest_m: FloatArray
    count: NDArray[np.int64]

    def as_dict(self) -> dict[str, float]:
        """``{"FR": mean, ...}``: the input mapping of the fuzzy engines."""
        return {name: float(v) for name, v in zip(SECTORS, self.mean_m, strict=True)}

    def nearest_by_direction(self) -> tuple[float, float, float]:
        """(front, rear, side): nearest return of the sectors whose bisector lies within 45° of ahead, of
        behind, and the rest. In HEX-90 that is FL+FR, RL+RR and LC+RC; in HEX the LC face, the RC face
        and the four others. inf where there is none."""
        out = []
        for mask in _direction_masks(self.layout):
            out.append(float(self.nearest_m[mask].min()) if mask.any() else math.inf)
        return out[0], out[1], out[2]


@lru_cache(maxsize=16)
def _direction_masks(layout: HexLayout) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    c = np.abs(np.array([layout.centre_deg(s) for s in SECTORS]))
    front, rear = c < 45.0, c > 135.0
    return front, rear, ~(front | rear)


@lru_cache(maxsize=16)
def _layout_tables(layout: HexLayout) -> tuple[float, FloatArray, NDArray[np.intp]]:
    """(first start in rad, sector edges relative to it in rad, canonical index of each layout sector)."""
    first = math.radians(layout.starts_deg[0])
    edges = np.radians(np.asarray(layout.starts_deg, dtype=np.float64)) - first
    to_canonical = np.array([SECTORS.index(s) for s in layout.order], dtype=np.intp)
    return first, edges, to_canonical


@lru_cache(maxsize=8)
def _beam_unit_vectors(n: int, angle_min: float, increment: float, yaw: float) -> tuple[FloatArray, FloatArray]:
    """cos and sin of every beam's bearing in the base frame; scans repeat their geometry, so cached."""
    a = yaw + angle_min + increment * np.arange(n, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    c.flags.writeable = False
    s.flags.writeable = False
    return c, s


def _check_scan(scan: LaserScan) -> FloatArray:
    ranges = np.asarray(scan.ranges_m, dtype=np.float64)
    if ranges.ndim != 1:
        raise ProtocolError(f"scan at t={scan.t}: ranges_m must be one-dimensional, got shape {ranges.shape}")
    numbers = {
        "angle_min_rad": scan.angle_min_rad,
        "angle_increment_rad": scan.angle_increment_rad,
        "range_min_m": scan.range_min_m,
        "range_max_m": scan.range_max_m,
        "sensor_pose.x_m": scan.sensor_pose.x_m,
        "sensor_pose.y_m": scan.sensor_pose.y_m,
        "sensor_pose.yaw_rad": scan.sensor_pose.yaw_rad,
    }
    for what, value in numbers.items():
        if not math.isfinite(value):
            raise ProtocolError(f"scan at t={scan.t}: {what} must be finite, got {value!r}")
    if scan.angle_increment_rad == 0.0 and len(ranges) > 1:
        raise ProtocolError(f"scan at t={scan.t}: angle_increment_rad is 0 for {len(ranges)} beams")
    if not 0.0 <= scan.range_min_m <= scan.range_max_m:
        raise ProtocolError(
            f"scan at t={scan.t}: need 0 <= range_min_m <= range_max_m, got {scan.range_min_m}, {scan.range_max_m}"
        )
    return ranges


@dataclass(frozen=True)
class BasePoints:
    """The valid returns of one scan in the base frame, polar: range and bearing from the base origin."""

    range_m: FloatArray
    bearing_rad: FloatArray


def scan_to_base(scan: LaserScan) -> BasePoints:
    """Drop invalid returns and move the rest to the base frame.

    Dropped: NaN, +inf, 0, and anything outside ``[range_min_m, range_max_m]``. Kept as an obstacle at
    the minimum range: -inf ("closer than the sensor can measure", docs/testing.md#what-the-robot-promises).
    Malformed scans raise `ProtocolError` naming the field.
    """
    ranges = _check_scan(scan)
    r = np.where(ranges == -np.inf, scan.range_min_m, ranges)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r > 0.0) & (r >= scan.range_min_m) & (r <= scan.range_max_m)
    pose: Pose2D = scan.sensor_pose
    c, s = _beam_unit_vectors(len(r), scan.angle_min_rad, scan.angle_increment_rad, pose.yaw_rad)
    rv = r[valid]
    x = pose.x_m + rv * c[valid]
    y = pose.y_m + rv * s[valid]
    return BasePoints(np.hypot(x, y), np.arctan2(y, x))


def sectorise(points: BasePoints, layout: HexLayout | str = HEX90, radius_m: float = DEFAULT_RADIUS_M) -> HexSectors:
    """Reduce base-frame points to the six sectors of ``layout`` (a `HexLayout` or its registry name)."""
    if isinstance(layout, str):
        layout = HEX_LAYOUTS.get(layout)
    if not (math.isfinite(radius_m) and radius_m > 0.0):
        raise ProtocolError(f"hex pattern: radius_m must be a positive number, got {radius_m!r}")
    first, edges, to_canonical = _layout_tables(layout)
    n = len(SECTORS)
    mean, nearest, count = np.empty(n), np.full(n, np.inf), np.zeros(n, dtype=np.int64)
    rel = np.mod(np.asarray(points.bearing_rad, dtype=np.float64) - first, 2.0 * math.pi)
    _sector_stats(rel, np.asarray(points.range_m, dtype=np.float64),
                  (edges, to_canonical), float(radius_m), (mean, nearest, count))
    return HexSectors(layout, float(radius_m), mean, nearest, count)


@njit(cache=True, nogil=True)
def _sector_stats(rel: FloatArray, range_m: FloatArray, layout: tuple[FloatArray, NDArray[np.intp]], radius_m: float,
                  out: tuple[FloatArray, FloatArray, NDArray[np.int64]]) -> None:  # pragma: no cover  compiled by numba
    """Each point's sector (the last of ``edges`` at or before its bearing ``rel`` from the first edge, as
    ``np.searchsorted(..., side="right") - 1``, a NaN bearing in the last), then per canonical sector the nearest
    range, and the mean of the ranges within ``radius_m`` summed in the points' order (``radius_m`` where none):
    what the numpy version computed with ``np.minimum.at`` and two ``np.bincount``, to the bit, in one pass instead
    of a dozen array calls a scan (the motion pipeline's hex pattern, ten times a second)."""
    edges, to_canonical = layout
    mean, nearest, count = out
    total = np.zeros(mean.shape[0])
    last = edges.shape[0] - 1
    for i in range(rel.shape[0]):
        b = rel[i]
        j = edges.shape[0] if math.isnan(b) else 0
        while j <= last and edges[j] <= b:
            j += 1
        k = to_canonical[min(max(j - 1, 0), last)]
        r = range_m[i]
        if r < nearest[k] or math.isnan(r):  # np.minimum: a NaN wins
            nearest[k] = r
        if r <= radius_m:
            count[k] += 1
            total[k] += r
    for k in range(mean.shape[0]):
        mean[k] = total[k] / count[k] if count[k] > 0 else radius_m


@functools.cache
def load_compiled() -> None:
    """Compile (a checkout's first run) or load (from numba's cache) `_sector_stats` when the motion pipeline is
    built, not at its first scan, with the argument types of `sectorise`'s call (a test checks that a running robot
    has one compiled version of each loop)."""
    _, edges, to_canonical = _layout_tables(HEX90)
    n = len(SECTORS)
    _sector_stats(np.zeros(1), np.ones(1), (edges, to_canonical), 1.0,
                  (np.empty(n), np.full(n, np.inf), np.zeros(n, dtype=np.int64)))


def hex_pattern(scan: LaserScan, layout: HexLayout | str = HEX90, radius_m: float = DEFAULT_RADIUS_M) -> HexSectors:
    """The six sectors of one scan: `scan_to_base` then `sectorise`."""
    return sectorise(scan_to_base(scan), layout, radius_m)


def ascii_drawing(layout: HexLayout | str, size: int = 11) -> str:
    """A text picture of ``layout`` seen from above, front (x) up, left (y) to the left.

    Each cell shows the first letter pair of the sector its bearing falls in; ``^^`` marks the base.
    """
    if isinstance(layout, str):
        layout = HEX_LAYOUTS.get(layout)
    first, edges, to_canonical = _layout_tables(layout)
    half = size // 2
    rows = []
    for i in range(size):
        cells = []
        for j in range(size):
            x, y = half - i, half - j  # row up = +x (front), column left = +y (left)
            if x == 0 and y == 0:
                cells.append("^^")
                continue
            if math.hypot(x, y) > half + 0.5:
                cells.append("  ")
                continue
            rel = (math.atan2(y, x) - first) % (2.0 * math.pi)
            k = int(np.searchsorted(edges, rel, side="right")) - 1
            cells.append(SECTORS[int(to_canonical[k])])
        rows.append(" ".join(cells).rstrip())
    return "\n".join(rows)


__all__ = [
    "DEFAULT_RADIUS_M",
    "HEX",
    "HEX90",
    "HEX_LAYOUTS",
    "SECTORS",
    "BasePoints",
    "HexLayout",
    "HexSectors",
    "ascii_drawing",
    "hex_pattern",
    "scan_to_base",
    "sectorise",
]
