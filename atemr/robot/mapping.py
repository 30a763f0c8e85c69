"""Where the robot's maps and poses come together: the active map, localization and a mapping session.

`MapService` owns the map store and the localization pipeline's map, and runs a SLAM session while the
agent is in MAPPING (scans come from the lidar's subscription, odometry from the localization's
``odom`` history). It is the one object that changes the active map, so localization, navigation and the
dashboard always agree on it; ``version`` changes whenever the map to draw changes.

A map change has a heavy half and a cheap one. `prepare` reads the map (up to the store's ``max_cells``)
and builds what localization and every map user (navigation's costmap) derive from it; it changes
nothing here, so any thread may run it: the dashboard gateway runs it in its own worker, off the control
loop. `swap` then installs the prepared map on the robot's thread between two ticks: a few assignments.
`activate` does both at once (start-up).

The active map's named places (`atemr.domain.places.Places`) come and go with it: read with the map in
`prepare`, installed by `swap`, changed by `set_places` (stored first, then used, so a failed write changes
nothing). A map just built by SLAM has none yet.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from atemr.domain.maps import OccupancyMap
from atemr.domain.places import NO_PLACES, Places
from atemr.errors import ConfigError, NavigationError
from atemr.io.map_store import MapStore
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.localizer import Localizer
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.slam import OccupancyGridSlam, SlamParams

log = logging.getLogger(__name__)

#: Redraw the growing map on the dashboard every this many integrated scans.
REDRAW_EVERY = 5


class MapUser(Protocol):
    """A part that derives something heavy from the active map (navigation's costmap and planners)."""

    def prepare_map(self, grid: OccupancyMap) -> object:
        """What this part derives from ``grid``; may run on any thread, so it must change nothing shared."""
        ...

    def use_map(self, grid: OccupancyMap, prepared: object | None) -> None:
        """Switch to ``grid`` (robot's thread); ``prepared`` is ``prepare_map(grid)``, or None: derive it now."""
        ...


class _Listener:
    """A plain ``listener(map)`` as a `MapUser` with nothing to prepare."""

    def __init__(self, listener: Callable[[OccupancyMap], None]) -> None:
        self.listener = listener

    def prepare_map(self, grid: OccupancyMap) -> object:
        return None

    def use_map(self, grid: OccupancyMap, prepared: object | None) -> None:
        self.listener(grid)


@dataclass(frozen=True, eq=False)
class PreparedMap:
    """A map read and ready to become the active one (`MapService.prepare`): hand it to `MapService.swap` once."""

    name: str
    grid: OccupancyMap
    localizer: Localizer
    #: What each map user prepared, in the order they were added.
    derived: tuple[object, ...]
    #: The map's named places, as stored.
    places: Places = NO_PLACES


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
        #: The active map's named places.
        self.places: Places = NO_PLACES
        self.version = 0
        self.slam: OccupancyGridSlam | None = None
        self.collecting = False
        self._registering = False
        self._lock = threading.RLock()
        self._users: list[MapUser] = []

    # -- the active map --------------------------------------------------------------------------------
    def on_map_change(self, listener: Callable[[OccupancyMap], None]) -> None:
        """Call ``listener(map)`` whenever the active map changes (cheap work only: it runs in the swap)."""
        self.add_map_user(_Listener(listener))

    def add_map_user(self, user: MapUser) -> None:
        """``user`` prepares its part of each new map in `prepare` and switches to it in `swap`."""
        with self._lock:
            self._users.append(user)

    def prepare(self, name: str, grid: OccupancyMap | None = None) -> PreparedMap:
        """Read map ``name`` from the store (or take ``grid``) and build what localization and the map users
        need of it. Heavy (up to the store's ``max_cells`` decoded, distance transforms) and changes nothing
        here: run it off the robot's thread. Raises `ConfigError` (unknown, unreadable, too large, or a map
        that cannot be localized against)."""
        grid = self.store.load(name) if grid is None else grid
        with self._lock:
            users = list(self._users)
        places = self.store.places(name) if self.store.exists(name) else NO_PLACES
        localizer = self.localization.prepare_map(grid)
        return PreparedMap(name, grid, localizer, tuple(user.prepare_map(grid) for user in users), places)

    def swap(self, prepared: PreparedMap, *, persist: bool = True) -> OccupancyMap:
        """Make a prepared map the active one (robot's thread, between ticks): assignments only. ``persist``
        records it as the selected map first (`ConfigError` if it was deleted meanwhile; nothing changes)."""
        if persist:
            self.store.set_active(prepared.name)
        grid = prepared.grid
        with self._lock:
            self.localization.set_map(grid, prepared.localizer)
            self.active_name, self.active = prepared.name, grid
            self.places = prepared.places
            self.version += 1
            derived = prepared.derived if len(prepared.derived) == len(self._users) else (None,) * len(self._users)
            for user, made in zip(self._users, derived, strict=True):
                user.use_map(grid, made)
        self.on_event("map", f"active map: {prepared.name}")
        return grid

    def activate(self, name: str, grid: OccupancyMap | None = None) -> OccupancyMap:
        """Make map ``name`` active and localize against it, here and now: read from the store and persisted
        as the selection, or ``grid`` as given (not persisted). Raises `ConfigError`. Heavy: start-up only;
        a running robot uses `prepare` off its thread, then `swap`."""
        return self.swap(self.prepare(name, grid), persist=grid is None)

    def set_places(self, places: Places) -> None:
        """Replace the active map's places: stored with the map first (`ConfigError` or `OSError`: nothing
        changes), then used by navigation and shown."""
        with self._lock:
            name = self.active_name
            if name is None or self.slam is not None:
                raise ConfigError("places are kept on a map: select a map first (and finish mapping)",
                                  path="places")
            self.store.save_places(name, places)
            self.places = places
        self.on_event("places", f"places of map {name}: {', '.join(places) or 'none'}")

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
            # Raises when the map is unusable: nothing stored yet. The SLAM pose is set on it below.
            self.localization.set_map(grid, pose_follows=True)
            try:
                stored = self.store.save(save_as, grid, activate=True)
            except Exception:
                if previous is not None:
                    self.localization.set_map(previous)
                raise
            self.slam, self.collecting = None, False
            self.active_name, self.active = stored, grid
            self.places = NO_PLACES
            self.version += 1
            for user in self._users:
                user.use_map(grid, None)
            try:
                self.localization.set_initial_pose(now, slam.current_pose)
            except NavigationError as exc:  # the map is stored and in use: say the robot is not localized on it
                self.localization.announce_not_localized(stored, f"the pose mapping ended at is not usable: {exc}")
        self.on_event("mapping", f"map saved as {stored}")
        return stored

    def drawable(self) -> OccupancyMap | None:
        """The growing map while mapping, else the active map."""
        with self._lock:
            if self.slam is not None:
                return self.slam.to_map("mapping", crop=False)
            return self.active
