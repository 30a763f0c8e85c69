"""From a `LaserScan` to the points every matcher uses: valid returns only, in the base frame.

NaN, 0, ±inf and ranges outside [range_min, range_max] are dropped, never used as distances
(docs/testing.md#what-the-robot-promises; -inf is an obstacle for the safety stop, but it has no position
to match). Beams are optionally thinned evenly, which is what AMCL's ``max_beams`` does: neighbouring beams
carry nearly the same information, and the filter's cost grows with their number.
"""

from __future__ import annotations

import numpy as np

from atemr.msgs import LaserScan
from atemr.skills.localization.geometry import FloatArray

#: An open beam (`open_ray_ends`) is trusted to this far short of the lidar's range (m).
OPEN_SHORT_M = 0.3


def valid_mask(scan: LaserScan) -> np.ndarray:
    """Which beams hold a usable range."""
    r = np.asarray(scan.ranges_m, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(r) & (r > 0.0) & (r >= scan.range_min_m) & (r <= scan.range_max_m)


def scan_points(scan: LaserScan, *, max_beams: int | None = None) -> FloatArray:
    """Valid returns as ``(M, 2)`` points in the base frame (x forward, y left).

    ``max_beams`` keeps at most that many valid beams, evenly spread over the valid ones. An empty
    result (no valid return at all) is a normal outcome the callers check for: an empty room or a
    covered sensor is not an error, but nothing can be matched against it.
    """
    r = np.asarray(scan.ranges_m, dtype=np.float64)
    ok = valid_mask(scan)
    idx = np.flatnonzero(ok)
    if max_beams is not None and 0 < max_beams < idx.size:
        idx = idx[np.linspace(0, idx.size - 1, max_beams).round().astype(np.intp)]
    return _base_points(scan, idx, r[idx])


def _base_points(scan: LaserScan, idx: np.ndarray, ranges: FloatArray | float) -> FloatArray:
    """The base-frame points ``ranges`` along the beams ``idx`` of ``scan`` (through its mounting pose)."""
    angles = scan.angle_min_rad + scan.angle_increment_rad * idx + scan.sensor_pose.yaw_rad
    m = scan.sensor_pose
    return np.column_stack([m.x_m + ranges * np.cos(angles), m.y_m + ranges * np.sin(angles)])


def open_ray_ends(scan: LaserScan, *, short_m: float = OPEN_SHORT_M) -> FloatArray:
    """Where the beams that met nothing within the lidar's range are known to pass freely: ``(F, 2)`` base-frame
    points ``short_m`` short of ``range_max_m`` along each beam whose range is +inf.

    +inf is a return beyond the range (REP 117; the RPLidar driver and the simulator both report it so): the
    beam crossed open space all that way, which a pose that puts a wall across it contradicts. A beam with no
    return at all (NaN: a dark or glossy surface, the RPLidar's distance 0) says nothing and is left out.
    ``short_m`` keeps a wall just beyond the range, drawn a cell or two nearer on the map, from counting.
    """
    r = np.asarray(scan.ranges_m, dtype=np.float64)
    reach = scan.range_max_m - short_m
    if reach <= 0:
        return np.zeros((0, 2))
    return _base_points(scan, np.flatnonzero(np.isposinf(r)), reach)


def sensor_origin(scan: LaserScan) -> tuple[float, float]:
    """The sensor's position in the base frame (where every beam starts)."""
    return scan.sensor_pose.x_m, scan.sensor_pose.y_m


__all__ = ["OPEN_SHORT_M", "open_ray_ends", "scan_points", "sensor_origin", "valid_mask"]
