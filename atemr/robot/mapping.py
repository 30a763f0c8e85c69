"""Where the robot's maps and poses come together: the active map, localization and a mapping session.

`MapService` owns the map store and the localization pipeline's map, and runs a SLAM session while the
agent is in MAPPING (scans come from the lidar's subscription, odometry from the localization's
``odom`` history). It is the one object that changes the active map, so localization, navigation and the
dashboard always agree on it; ``version`` changes whenever the map to draw changes.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from atemr.errors import NavigationError
from atemr.io.map_store import MapStore
from atemr.io.sim.maps import OccupancyMap
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.slam import OccupancyGridSlam, SlamParams

log = logging.getLogger(__name__)

#: Redraw the growing map on the dashboard every this many integrated scans.
REDRAW_EVERY = 5


class MapService:
    """The active map, its changes, and the mapping session (see the module docstring)."""

    def __init__(self, store: MapStore, localization: LocalizationPipeline, slam_params: SlamParams,
                 on_event: Callable[[str, str], None] | None = None) -> None:
        self.store = store
        self.localization = localization
        self.slam_params = slam_params
        self.on_event = on_event or (lambda kind, text: None)
        self.active_name: str | None = None
        self.active: OccupancyMap | None = None
        self.version = 0
        self.slam: OccupancyGridSlam | None = None
        self.collecting = False
        self._registering = False
        self._lock = threading.RLock()
        self._listeners: list[Callable[[OccupancyMap], None]] = []

    # -- the active map --------------------------------------------------------------------------------
    def on_map_change(self, listener: Callable[[OccupancyMap], None]) -> None:
        """Call ``listener(map)`` whenever the active map changes (navigation rebuilds its costmap)."""
        self._listeners.append(listener)

    def activate(self, name: str, grid: OccupancyMap | None = None) -> OccupancyMap:
        """Make stored map ``name`` active (persisted) and localize against it; raises `ConfigError`."""
        with self._lock:
            grid = self.store.select(name) if grid is None else grid
            self.active_name, self.active = name, grid
            self.localization.set_map(grid)
            self.version += 1
            for listener in self._listeners:
                listener(grid)
        self.on_event("map", f"active map: {name}")
        return grid

    # -- mapping -----------------------------------------------------------------------------------------
    def begin(self) -> None:
        """Start a SLAM session at the current pose: in the active map's frame when localized (the first scan
        is registered to the active map, so the new map keeps its frame), else where odometry is."""
        with self._lock:
            if self.slam is not None:
                raise NavigationError("a mapping session is already running")
            start = self.localization.map_pose()
            anchor = self.active if start is not None else None
            self.slam = OccupancyGridSlam(self.slam_params, start=start or Pose2D(), anchor=anchor)
            self._registering = anchor is not None
            self.collecting = True
            self.version += 1
        where = f"in the frame of map {self.active_name}" if anchor is not None else "at the odometry pose"
        self.on_event("mapping", f"mapping started {where}")

    def on_scan(self, scan: LaserScan) -> None:
        """Lidar subscription: integrate the scan while a session collects."""
        unregistered = False
        with self._lock:
            if self.slam is None or not self.collecting:
                return
            if self.slam.update(self.localization.odom_at(scan.t), scan) and self.slam.updates % REDRAW_EVERY == 0:
                self.version += 1
            if self._registering and self.slam.trajectory:
                self._registering = False
                unregistered = not self.slam.anchored
        if unregistered:
            self.on_event("mapping", f"the first scan does not fit map {self.active_name}: the new map's frame is "
                          "the localized start pose, unrefined")

    def pause(self) -> None:
        """Stop adding scans (END MAP); the map waits for save or discard."""
        with self._lock:
            self.collecting = False

    def end(self, save_as: str | None, now: float) -> str | None:
        """Finish the session: save the map as ``save_as`` (it becomes active, localized where the robot
        is) or discard it (None). Returns the stored name.

        Saving checks the map first (localization must be able to use it) and only then stores it; if
        either step fails the session stays as it was, so the operator can keep mapping or try another
        name: nothing is half-saved and nothing is lost.
        """
        with self._lock:
            slam = self.slam
            if slam is None:
                raise NavigationError("no mapping session is running")
            if save_as is None:
                self.slam, self.collecting = None, False
                self.version += 1
                self.on_event("mapping", "map discarded")
                return None
            grid = slam.to_map(save_as)
            previous = self.active
            self.localization.set_map(grid)  # raises when the map is unusable: nothing stored yet
            try:
                stored = self.store.save(save_as, grid, activate=True)
            except Exception:
                if previous is not None:
                    self.localization.set_map(previous)
                raise
            self.slam, self.collecting = None, False
            self.active_name, self.active = stored, grid
            self.version += 1
            for listener in self._listeners:
                listener(grid)
            self.localization.set_initial_pose(now, slam.current_pose)
        self.on_event("mapping", f"map saved as {stored}")
        return stored

    def drawable(self) -> OccupancyMap | None:
        """The growing map while mapping, else the active map."""
        with self._lock:
            if self.slam is not None:
                return self.slam.to_map("mapping", crop=False)
            return self.active
