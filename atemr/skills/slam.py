"""Occupancy-grid SLAM while the operator drives: log-odds mapping with scan-to-map matching.

Front end (every time the robot has moved ``update_min_d_m`` or turned ``update_min_a_rad``):

1. **predict** the pose by the odometry increment since the last update;
2. **match** the scan against the map built so far — point-to-line ICP onto the occupied cells (the
   whole grid, not just the previous scan, so errors do not accumulate scan by scan). A match that does
   not converge, keeps too few inliers or jumps implausibly far from the prediction is refused and the
   prediction is kept;
3. **loop closure by re-matching against the grid**: every ``rematch_every`` updates, and whenever ICP
   refused, the scan is also matched by a correlative search over a wider window against the grid's
   likelihood field (`ScanToMapMatcher`), which pulls the pose back onto the walls mapped long ago
   when the robot returns to a known place after a drift that ICP alone could not undo;
4. **integrate** the scan: every beam's cells from the sensor to just before the end point get
   ``l_free``, the end point's cell ``l_occ`` (inverse sensor model, Probabilistic Robotics §9.2), all
   beams at once — points are sampled along each ray at half a cell and de-duplicated per scan, so a
   cell gets at most one update per scan however many beams cross it. Log-odds are clamped so a
   moving person or a door that opened can be overwritten later.

The map's frame is the pose given at the start (the robot's start pose by default, as in ROS
slam_toolbox). When the robot is localized on a map already (a remap of a changed flat, or mapping
rooms the old map missed), that map can be given as the ``anchor``: the first scan is registered to it
(correlative search and ICP around the start pose, `ScanToMapMatcher`), so the new map shares the old
map's frame to a fraction of a cell and a fraction of a degree. That matters for more than looks: the
grid is axis-aligned with its frame, so a start heading off by a third of a degree (a good AMCL
estimate) staircases every long wall and moves the far end of the flat by centimetres, and poses and
missions written on the old map would not carry over. Only the first scan uses the anchor; the map is
built from the scans alone, so a moved sofa is mapped where it now stands.

`to_map` exports the known part as an `OccupancyMap` that `save_map` writes in the map_server format.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from atemr.domain.maps import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from atemr.errors import ConfigError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, compose, is_finite_pose, relative
from atemr.skills.localization.icp import IcpParams, IcpTarget, icp
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.scan import scan_points, valid_mask
from atemr.skills.localization.scan_to_map import ScanToMapMatcher

#: Fewest points (scan returns, or mapped cells) a match is tried with.
MIN_POINTS = 20
#: A mapped cell's surface line is fitted only from cells within this many cells of it (`IcpParams.normal_radius_m`):
#: a wall's ten nearest cells lie within five; a table leg's reach the next leg.
NORMAL_RADIUS_CELLS = 6


def logodds(p: float) -> float:
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class SlamParams:
    """Grid, sensor model and front-end settings."""

    resolution_m: float = 0.05
    #: Side of the square grid centred on the start pose (a flat fits in 30 m).
    size_m: float = 30.0
    p_occ: float = 0.7
    p_free: float = 0.4
    clamp_logodds: float = 4.0
    #: Returns beyond this are used only to clear space, up to it (long beams are the least accurate).
    max_range_m: float = 7.5
    update_min_d_m: float = 0.1
    update_min_a_rad: float = 0.1
    rematch_every: int = 10
    #: A match farther than this from the odometry prediction is refused (m, rad).
    max_correction_m: float = 0.3
    max_correction_rad: float = 0.3
    min_inlier_fraction: float = 0.5
    #: False: map from odometry alone (a baseline to compare with, or for a robot whose scans cannot be matched).
    match_scans: bool = True
    #: Search window of the first scan's registration to an anchor map around the start pose (m, rad), and the
    #: least agreement (share of beams ending on the anchor's walls) for the registration to be used.
    anchor_window_m: float = 0.2
    anchor_window_rad: float = 0.1
    anchor_min_agreement: float = 0.6

    def __post_init__(self) -> None:
        for name in ("resolution_m", "size_m", "clamp_logodds", "max_range_m", "max_correction_m",
                     "max_correction_rad", "anchor_window_m", "anchor_window_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"mapping.{name}")
        if not 0.5 < self.p_occ < 1.0 or not 0.0 < self.p_free < 0.5:
            raise ConfigError(f"need 0.5 < p_occ < 1 and 0 < p_free < 0.5, got {self.p_occ}, {self.p_free}",
                              path="mapping.p_occ")
        if self.size_m / self.resolution_m > 8000:
            raise ConfigError(f"grid of {self.size_m} m at {self.resolution_m} m is too large", path="mapping.size_m")
        if not 0.0 <= self.anchor_min_agreement <= 1.0:
            raise ConfigError(f"must be within [0, 1], got {self.anchor_min_agreement!r}",
                              path="mapping.anchor_min_agreement")
        if self.rematch_every < 1:
            raise ConfigError(f"must be >= 1, got {self.rematch_every}", path="mapping.rematch_every")


class OccupancyGridSlam:
    """The map being built and the robot's pose in it. Feed it scans with the odometry of their time.

    ``anchor``: a map the robot is localized on at ``start``; the first scan is registered to it (see the
    module docstring). ``anchored`` says whether that registration was used.
    """

    def __init__(self, params: SlamParams | None = None, *, start: Pose2D | None = None,
                 anchor: OccupancyMap | None = None) -> None:
        self.params = p = params or SlamParams()
        start = start or Pose2D()
        if not is_finite_pose(start):
            raise ConfigError(f"mapping: start pose must be finite, got {start}", path="mapping.start")
        n = round(p.size_m / p.resolution_m)
        self.logodds = np.zeros((n, n), dtype=np.float32)
        #: World coordinates of the grid's lower-left corner (the grid is axis-aligned with the map frame).
        self.origin_xy = (start.x_m - n * p.resolution_m / 2.0, start.y_m - n * p.resolution_m / 2.0)
        self.pose: FloatArray = as_array(start)
        self.trajectory: list[Pose2D] = []
        self.updates = 0
        self.refused = 0
        self.rematched = 0
        self._odom: FloatArray | None = None
        self._anchor = anchor
        self.anchored = False
        self._l_occ = logodds(p.p_occ)
        self._l_free = logodds(p.p_free)

    # -- the per-scan step -------------------------------------------------------------------------
    def update(self, odom: Pose2D, scan: LaserScan) -> bool:
        """Process one scan taken at odometry pose ``odom``; True when it was matched and integrated."""
        p = self.params
        if not is_finite_pose(odom):
            self.refused += 1
            return False
        o = as_array(odom)
        if self._odom is None:
            self._odom = o
            if self._anchor is not None:
                self._register_to_anchor(scan)
            self._integrate(scan)
            return True
        inc = relative(self._odom, o)
        if math.hypot(inc[0], inc[1]) < p.update_min_d_m and abs(inc[2]) < p.update_min_a_rad:
            return False
        self._odom = o
        predicted = compose(self.pose, inc)
        self.pose = self._match(self._points(scan), predicted) if p.match_scans else predicted
        self._integrate(scan)
        return True

    def _register_to_anchor(self, scan: LaserScan) -> None:
        """Move the start pose onto the anchor map (the first scan only); kept as given when the scan does not
        fit there well enough (the flat changed, or the start pose was wrong)."""
        p = self.params
        anchor, self._anchor = self._anchor, None
        assert anchor is not None
        if not anchor.occupied.any():
            return
        points = self._points(scan)
        if points.shape[0] < MIN_POINTS:
            return
        match = ScanToMapMatcher(LikelihoodField(anchor)).match(points, as_pose(self.pose),
                                                                window_xy_m=p.anchor_window_m,
                                                                window_yaw_rad=p.anchor_window_rad)
        if match.agreement >= p.anchor_min_agreement:
            self.pose = as_array(match.pose)
            self.anchored = True

    def _points(self, scan: LaserScan) -> FloatArray:
        """The scan's returns in the base frame, up to ``max_range_m`` (what matching trusts)."""
        points = scan_points(scan)
        return points[np.hypot(points[:, 0], points[:, 1]) <= self.params.max_range_m]

    def _plausible(self, pose: FloatArray, predicted: FloatArray) -> bool:
        d = relative(predicted, pose)
        return math.hypot(d[0], d[1]) <= self.params.max_correction_m and abs(d[2]) <= self.params.max_correction_rad

    def _match(self, points: FloatArray, predicted: FloatArray) -> FloatArray:
        p = self.params
        target = self.occupied_points()
        if points.shape[0] < MIN_POINTS or target.shape[0] < MIN_POINTS:
            return predicted
        # the map's own cells: a line only where neighbouring cells form one (not a line from leg to leg)
        target_params = IcpParams(max_correspondence_m=0.3, normal_radius_m=NORMAL_RADIUS_CELLS * p.resolution_m)
        result = icp(points, IcpTarget(target, target_params), as_pose(predicted))
        pose = as_array(result.pose)
        ok = result.ok and result.inlier_fraction >= p.min_inlier_fraction and self._plausible(pose, predicted)
        if not ok:
            self.refused += 1
            pose = predicted
        self.updates += 1
        if not ok or self.updates % p.rematch_every == 0:
            grid = self.to_map("slam")
            if grid.occupied.any():
                match = ScanToMapMatcher(LikelihoodField(grid)).match(points, as_pose(pose), window_xy_m=0.25,
                                                                      window_yaw_rad=0.15)
                candidate = as_array(match.pose)
                if match.agreement >= 0.6 and self._plausible(candidate, predicted):
                    pose = candidate
                    self.rematched += 1
        return pose

    # -- mapping -----------------------------------------------------------------------------------
    def _cells(self, x: FloatArray, y: FloatArray) -> NDArray[np.intp]:
        """Flat indices of world points (-1 outside the grid)."""
        res = self.params.resolution_m
        n = self.logodds.shape[0]
        col = np.floor((x - self.origin_xy[0]) / res).astype(np.intp)
        row = np.floor((y - self.origin_xy[1]) / res).astype(np.intp)
        inside = (col >= 0) & (col < n) & (row >= 0) & (row < n)
        return np.where(inside, row * n + col, -1)

    def _integrate(self, scan: LaserScan) -> None:
        """Inverse sensor model for all beams of ``scan`` at the current pose."""
        p = self.params
        res = p.resolution_m
        ok = valid_mask(scan)
        r = np.asarray(scan.ranges_m, dtype=np.float64)
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            self.trajectory.append(as_pose(self.pose))
            return
        hit = r[idx] <= p.max_range_m
        rr = np.minimum(r[idx], p.max_range_m)
        sensor = compose(self.pose, as_array(scan.sensor_pose))
        ang = sensor[2] + scan.angle_min_rad + scan.angle_increment_rad * idx
        # free cells: samples every half cell from the sensor to one cell short of the end point
        steps = np.arange(0.0, float(rr.max()), res / 2.0)
        along = steps[None, :]
        inside = along < (rr - res)[:, None]
        xs = sensor[0] + along * np.cos(ang)[:, None]
        ys = sensor[1] + along * np.sin(ang)[:, None]
        free = np.unique(self._cells(xs[inside], ys[inside]))
        ex = sensor[0] + rr[hit] * np.cos(ang[hit])
        ey = sensor[1] + rr[hit] * np.sin(ang[hit])
        occ = np.unique(self._cells(ex, ey))
        occ = occ[occ >= 0]
        free = np.setdiff1d(free[free >= 0], occ, assume_unique=True)
        flat = self.logodds.ravel()
        flat[free] += self._l_free
        flat[occ] += self._l_occ
        np.clip(flat, -p.clamp_logodds, p.clamp_logodds, out=flat)
        self.trajectory.append(as_pose(self.pose))

    # -- output ------------------------------------------------------------------------------------
    @property
    def current_pose(self) -> Pose2D:
        return as_pose(self.pose)

    def occupied_points(self) -> FloatArray:
        """World coordinates of the cells currently believed occupied (p > 0.65)."""
        rows, cols = np.nonzero(self.logodds > logodds(0.65))
        res = self.params.resolution_m
        return np.column_stack([self.origin_xy[0] + (cols + 0.5) * res, self.origin_xy[1] + (rows + 0.5) * res])

    def to_map(self, name: str = "map", *, crop: bool = True, margin_cells: int = 5) -> OccupancyMap:
        """The map as a trinary `OccupancyMap` (p > 0.65 occupied, p < 0.196 free, else unknown).

        ``crop`` keeps only the bounding box of the known cells plus a margin, as a saved map should.
        """
        lo = self.logodds
        data = np.full(lo.shape, UNKNOWN, dtype=np.int8)
        data[lo < logodds(0.196)] = FREE
        data[lo > logodds(0.65)] = OCCUPIED
        res = self.params.resolution_m
        r0, c0 = 0, 0
        if crop:
            rows, cols = np.nonzero(data != UNKNOWN)
            if rows.size:
                n = lo.shape[0]
                r0, r1 = max(0, int(rows.min()) - margin_cells), min(n, int(rows.max()) + margin_cells + 1)
                c0, c1 = max(0, int(cols.min()) - margin_cells), min(n, int(cols.max()) + margin_cells + 1)
                data = data[r0:r1, c0:c1]
        origin = Pose2D(self.origin_xy[0] + c0 * res, self.origin_xy[1] + r0 * res, 0.0)
        return OccupancyMap(np.ascontiguousarray(data), res, origin, name=name)



def map_agreement(built: OccupancyMap, truth: OccupancyMap) -> tuple[float, float]:
    """How well a built map matches a true one, within one cell: (precision, recall).

    Precision: the share of the built map's occupied cells that lie within one cell of a true occupied cell
    (what it drew is really there). Recall: the share of the true surfaces it saw (true occupied cells next to
    space the built map knows is free) that have a built occupied cell within one cell. The maps may differ in
    origin and size; cells are matched by their world position.
    """
    near = np.ones((3, 3), bool)
    rows, cols = np.nonzero(built.occupied)
    r, c = truth.world_to_cell(*built.cell_to_world(rows, cols))
    inside = truth.contains(r, c)
    true_near = ndimage.binary_dilation(truth.occupied, near)
    precision = float(np.mean(inside & true_near[np.where(inside, r, 0), np.where(inside, c, 0)])) if len(r) else 0.0
    fr, fc = np.nonzero(built.free)
    tr, tc = truth.world_to_cell(*built.cell_to_world(fr, fc))
    ok = truth.contains(tr, tc)
    seen = np.zeros(truth.data.shape, bool)
    seen[tr[ok], tc[ok]] = True
    surface = truth.occupied & ndimage.binary_dilation(seen, near)
    built_occupied = np.zeros(truth.data.shape, bool)
    built_occupied[r[inside], c[inside]] = True
    recall = float((ndimage.binary_dilation(built_occupied, near) & surface).sum() / max(1, surface.sum()))
    return precision, recall


__all__ = ["OccupancyGridSlam", "SlamParams", "logodds", "map_agreement"]
