"""From a `LaserScan` to the points every matcher uses: valid returns only, in the base frame.

NaN, 0, ±inf and ranges outside [range_min, range_max] are dropped, never used as distances
(docs/testing.md#what-the-robot-promises; -inf is an obstacle for the safety stop, but it has no position
to match). Beams are optionally thinned evenly, which is what AMCL's ``max_beams`` does: neighbouring beams
carry nearly the same information, and the filter's cost grows with their number.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from atemr.msgs import LaserScan
from atemr.skills.localization.geometry import FloatArray

#: An open beam (`open_ray_ends`) is trusted to this far short of the lidar's range (m).
OPEN_SHORT_M = 0.3
#: Beams without a return (NaN) count as open only in runs of at least this many neighbours: a lone one is a
#: dropout or a dark spot, a run is a direction with nothing within the device's reach.
SILENT_RUN = 3


@lru_cache(maxsize=64)
def evenly_spread(count: int, keep: int) -> NDArray[np.intp]:
    """The indices of ``keep`` of ``count`` items spread evenly from the first to the last (read-only): how every
    matcher thins a scan. Scans come in a few sizes, so each is worked out once."""
    out = np.linspace(0, count - 1, keep).round().astype(np.intp)
    out.setflags(write=False)
    return out


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
        idx = idx[evenly_spread(idx.size, max_beams)]
    return _base_points(scan, idx, r[idx])


def _base_points(scan: LaserScan, idx: np.ndarray, ranges: FloatArray | float) -> FloatArray:
    """The base-frame points ``ranges`` along the beams ``idx`` of ``scan`` (through its mounting pose)."""
    angles = scan.angle_min_rad + scan.angle_increment_rad * idx + scan.sensor_pose.yaw_rad
    m = scan.sensor_pose
    return np.column_stack([m.x_m + ranges * np.cos(angles), m.y_m + ranges * np.sin(angles)])


def open_ray_ends(scan: LaserScan, *, short_m: float = OPEN_SHORT_M, silent_run: int = SILENT_RUN) -> FloatArray:
    """Where the beams that met nothing within the lidar's range are known to pass freely: ``(F, 2)`` base-frame
    points ``short_m`` short of ``range_max_m`` along each beam whose range is +inf, or that lies in a run of
    at least ``silent_run`` neighbouring beams without a return (NaN).

    +inf is a return beyond the range (REP 117; the RPLidar driver and the simulator both report it so): the
    beam crossed open space all that way, which a pose that puts a wall across it contradicts. NaN is no return
    at all (the RPLidar's distance 0): nothing within the device's reach (12 m on an A2M8), or a dropout, or a
    dark or glossy spot. A lone one says nothing. A run of them is a direction that is open beyond the device's
    reach: down a warehouse's aisle, most beams are silent, and they are what tells its look-alike bays apart
    (`benchmarks/global_localization.py`: 66 → 76 % localized there). Mapped structure is what a lidar returned
    from when the map was made, so a wall on the map across such a run contradicts the pose. A run can also be
    glass, a mirror or a black surface in front of a mapped wall: then it counts against the true place too.
    That weakens an answer, it does not make a wrong one: the decision needs one place clearly better on all the
    evidence (10-60 neighbouring beams blanked near walls at 30 poses each on two maps changed no answer).
    ``short_m`` keeps a wall just beyond the range, drawn a cell or two nearer on the map, from counting.
    """
    r = np.asarray(scan.ranges_m, dtype=np.float64)
    reach = scan.range_max_m - short_m
    if reach <= 0:
        return np.zeros((0, 2))
    revolution = abs(r.size * scan.angle_increment_rad - 2.0 * math.pi) < abs(scan.angle_increment_rad)
    silent = _in_runs(np.isnan(r), silent_run, wrap=revolution)
    return _base_points(scan, np.flatnonzero(np.isposinf(r) | silent), reach)


def _in_runs(flags: np.ndarray, length: int, *, wrap: bool) -> np.ndarray:
    """Which of ``flags`` lie in a run of at least ``length`` true neighbours (``wrap``: a whole revolution, whose
    last beam neighbours the first). The runs are read off the true flags' indices (a scan holds a few silent
    beams, dropouts most of them), so the cost is that of the few, not a dozen array passes over the scan."""
    n = flags.size
    if length <= 1 or n == 0:
        return flags.copy()
    out = np.zeros(n, dtype=bool)
    on: list[int] = np.flatnonzero(flags).tolist()
    if length > n or len(on) < length:
        return out
    if len(on) == n:  # all true: one run (round the whole revolution, or end to end)
        out[:] = True
        return out
    runs: list[tuple[int, int]] = []  # [start, end) of each run of consecutive true flags
    start = prev = on[0]
    for index in on[1:]:
        if index != prev + 1:
            runs.append((start, prev + 1))
            start = index
        prev = index
    runs.append((start, prev + 1))
    if wrap and len(runs) > 1 and runs[0][0] == 0 and runs[-1][1] == n:  # the last run goes on into the first
        (_, head_end), (tail_start, _) = runs[0], runs[-1]
        if head_end + (n - tail_start) >= length:
            out[:head_end] = True
            out[tail_start:] = True
        runs = runs[1:-1]
    for begin, end in runs:
        if end - begin >= length:
            out[begin:end] = True
    return out


def sensor_origin(scan: LaserScan) -> tuple[float, float]:
    """The sensor's position in the base frame (where every beam starts)."""
    return scan.sensor_pose.x_m, scan.sensor_pose.y_m


__all__ = ["OPEN_SHORT_M", "SILENT_RUN", "evenly_spread", "open_ray_ends", "scan_points", "sensor_origin", "valid_mask"]
