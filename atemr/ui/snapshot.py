"""Turning the robot's data into the dashboard's JSON snapshot and map image (for `RobotGateway`
implementations): pure functions, numpy-vectorised, no I/O.

The gateway calls these at 10 Hz, so they are cheap: scans are transformed in one array operation and
decimated to a bounded number of points, coordinates are rounded to millimetres, and the map image is
rendered only when its version changes (the caller keeps the `MapImage` until then).
"""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from atemr.errors import ConfigError
from atemr.msgs import LaserScan, Pose2D
from atemr.ui.gateway import MapImage
from atemr.ui.state import NavigationJson, PoseJson, SystemJson

if TYPE_CHECKING:
    from atemr.io.can.protocol import PrimaryStatus
    from atemr.io.system_monitor import SystemSample
    from atemr.skills.nav.navigator import NavStatus

#: Most points sent per scan or path (a phone draws 360 points at 10 Hz without effort).
MAX_POINTS = 720
#: Grey levels of the rendered map, as ROS map_saver writes them.
FREE_GREY, OCCUPIED_GREY, UNKNOWN_GREY = 254, 0, 205


class GridLike(Protocol):
    """What `render_map` needs of an occupancy grid (`atemr.domain.maps.OccupancyMap` has it)."""

    @property
    def data(self) -> NDArray[np.int8]: ...

    @property
    def resolution_m(self) -> float: ...

    @property
    def origin(self) -> Pose2D: ...


def pose_json(pose: Pose2D | None) -> PoseJson | None:
    """``{"x_m", "y_m", "yaw_rad"}`` rounded for the wire, or None (not localized)."""
    if pose is None:
        return None
    values = (pose.x_m, pose.y_m, pose.yaw_rad)
    if not all(math.isfinite(v) for v in values):
        return None
    return {"x_m": round(pose.x_m, 4), "y_m": round(pose.y_m, 4), "yaw_rad": round(pose.yaw_rad, 4)}


def points_json(xy: NDArray[np.float64] | list[Any] | None, max_points: int = MAX_POINTS) -> list[list[float]]:
    """An (N, 2) array of points as ``[[x, y], ...]``: non-finite rows dropped, evenly decimated to at most
    ``max_points``, rounded to millimetres."""
    if xy is None:
        return []
    arr = np.asarray(xy, dtype=np.float64)
    if arr.size == 0:
        return []
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ConfigError(f"points must be an (N, 2) array, got shape {arr.shape}")
    arr = arr[np.isfinite(arr).all(axis=1)]
    if len(arr) > max_points:
        arr = arr[np.linspace(0, len(arr) - 1, max_points).round().astype(np.intp)]
    return np.round(arr, 3).tolist()


def scan_points(scan: LaserScan, pose: Pose2D) -> NDArray[np.float64]:
    """The scan's valid returns as map-frame points (N, 2), the robot being at ``pose``.

    Valid means finite and within [range_min, range_max] (NaN, ±inf, 0 and out-of-range are dropped:
    the dashboard draws what was seen, not the stop-zone convention for -inf).
    """
    ranges = np.asarray(scan.ranges_m, dtype=np.float64)
    angles = scan.angles_rad
    ok = np.isfinite(ranges) & (ranges >= scan.range_min_m) & (ranges <= scan.range_max_m) & (ranges > 0)
    r, a = ranges[ok], angles[ok]
    sp = scan.sensor_pose
    # sensor frame → base frame
    bx = sp.x_m + r * np.cos(a + sp.yaw_rad)
    by = sp.y_m + r * np.sin(a + sp.yaw_rad)
    # base frame → map frame
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    return np.column_stack((pose.x_m + c * bx - s * by, pose.y_m + s * bx + c * by))


def status_levels(status: PrimaryStatus) -> tuple[dict[str, bool], dict[str, bool]]:
    """Level-1 (agent bits) and level-2 (hardware bits) states of a 0x153 status, names in lower case."""
    level1 = {name.lower(): ok for name, ok in status.agent_ok().items()}
    level2 = {name.lower(): ok for name, ok in status.hardware_ok().items()}
    return level1, level2


def navigation_json(status: NavStatus) -> NavigationJson:
    """Distance left along the path and the time to go, rounded; None for what the planner does not know."""

    def known(value: float, digits: int) -> float | None:
        return round(value, digits) if math.isfinite(value) and value >= 0.0 else None

    return {"distance_left_m": known(status.distance_left_m, 2), "eta_s": known(status.eta_s, 1)}


def system_json(sample: SystemSample | None) -> SystemJson | None:
    """The 1 Hz host sample (`atemr.io.system_monitor.SystemMonitor.latest`) for the graph."""
    if sample is None:
        return None
    return {"t": round(sample.t, 2), "cpu_percent": round(sample.cpu_percent, 2),
            "memory_percent": round(sample.memory_percent, 2), "disk_percent": round(sample.disk_percent, 2)}


def render_map(grid: GridLike, version: int) -> MapImage:
    """The occupancy grid as a greyscale PNG the browser draws (free white, occupied black, unknown grey,
    ``scale`` probabilities in between), image row 0 at the top as map_saver writes it."""
    data = np.asarray(grid.data)
    if data.ndim != 2 or data.size == 0:
        raise ConfigError(f"a map grid must be a non-empty 2-D array, got shape {data.shape}")
    values = data.astype(np.float64)
    grey = np.where(
        values < 0, UNKNOWN_GREY, np.round(FREE_GREY - np.clip(values, 0, 100) / 100.0 * (FREE_GREY - OCCUPIED_GREY))
    ).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(grey[::-1]), mode="L").save(buf, format="PNG", optimize=False)
    height, width = data.shape
    return MapImage(buf.getvalue(), int(width), int(height), float(grid.resolution_m), grid.origin, int(version))
