"""Moving obstacles: people and pets seen in the scan, tracked from scan to scan, and where they will be.

A costmap holds where things *are*; a person walking across the room will be somewhere else a second
later, and a robot that plans only with the present steps into her way. This tracker gives the costmap
where moving things are *going*:

1. Segments: the scan's returns that the map does not explain (the costmap hands them over), in beam
   order, split wherever two neighbouring returns are farther apart than ``gap_m`` (classic laser
   segmentation; one vectorised ``diff``). Each segment's centroid and half-extent.
2. Tracks: each segment is matched to the nearest track within ``gate_m`` (greedy by distance, all pairs
   at once); the track's velocity is smoothed with an exponential filter. Unmatched segments start tracks;
   tracks not seen for ``forget_s`` are dropped.
3. Prediction: a track seen ``min_hits`` times moving faster than ``min_speed_mps`` is swept forward over
   ``horizon_s``: disks of its half-extent along ``c + v·τ``, returned as points for the costmap's
   predicted layer. Slow or new tracks (furniture seen from a moving robot, noise) predict nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from atemr.errors import NavigationError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TrackerParams:
    gap_m: float = 0.15
    gate_m: float = 0.4
    smoothing: float = 0.5
    min_hits: int = 3
    min_speed_mps: float = 0.2
    max_speed_mps: float = 2.0
    horizon_s: float = 1.5
    step_s: float = 0.25
    forget_s: float = 0.5
    max_extent_m: float = 0.6

    def __post_init__(self) -> None:
        for name in ("gap_m", "gate_m", "min_speed_mps", "max_speed_mps", "horizon_s", "step_s", "forget_s",
                     "max_extent_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise NavigationError(f"tracker: {name} must be a finite number > 0, got {value!r}")
        if not 0 < self.smoothing <= 1:
            raise NavigationError(f"tracker: smoothing must be within (0, 1], got {self.smoothing!r}")


@dataclass
class Track:
    """One moving (or not) thing: where, how fast, how big, how often seen."""

    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    radius_m: float
    t: float
    hits: int = 1

    @property
    def speed_mps(self) -> float:
        return math.hypot(self.vx_mps, self.vy_mps)


def segments(points: FloatArray, gap_m: float) -> tuple[FloatArray, FloatArray]:
    """Centroids (S, 2) and half-extents (S,) of the runs of consecutive points closer than ``gap_m``."""
    if len(points) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    jumps = np.hypot(*np.diff(points, axis=0).T) > gap_m
    label = np.concatenate([[0], np.cumsum(jumps)])
    n = int(label[-1]) + 1
    count = np.bincount(label, minlength=n).astype(np.float64)
    cx = np.bincount(label, points[:, 0], n) / count
    cy = np.bincount(label, points[:, 1], n) / count
    spread = np.hypot(points[:, 0] - cx[label], points[:, 1] - cy[label])
    half = np.zeros(n)
    np.maximum.at(half, label, spread)
    return np.column_stack([cx, cy]), half


class ObstacleTracker:
    """Tracks the unmapped segments of successive scans; see the module doc."""

    def __init__(self, params: TrackerParams | None = None) -> None:
        self.params = params or TrackerParams()
        self.tracks: list[Track] = []

    def reset(self) -> None:
        self.tracks = []

    def update(self, t: float, points: FloatArray) -> list[Track]:
        """Fold in the unmapped returns (world points, in beam order) of the scan taken at ``t``."""
        p = self.params
        self.tracks = [tr for tr in self.tracks if t - tr.t <= p.forget_s]
        centres, half = segments(np.asarray(points, dtype=np.float64).reshape(-1, 2), p.gap_m)
        keep = half <= p.max_extent_m  # a long wall segment is not a person
        centres, half = centres[keep], half[keep]
        matched_tracks: set[int] = set()
        matched_segs: set[int] = set()
        if self.tracks and len(centres):
            prev = np.array([(tr.x_m, tr.y_m) for tr in self.tracks])
            d = np.hypot(centres[:, None, 0] - prev[None, :, 0], centres[:, None, 1] - prev[None, :, 1])
            for flat in np.argsort(d, axis=None):
                si, ti = divmod(int(flat), len(self.tracks))
                if d[si, ti] > p.gate_m:
                    break
                if si in matched_segs or ti in matched_tracks:
                    continue
                matched_segs.add(si)
                matched_tracks.add(ti)
                tr = self.tracks[ti]
                dt = t - tr.t
                if dt <= 0:
                    continue
                vx = (centres[si, 0] - tr.x_m) / dt
                vy = (centres[si, 1] - tr.y_m) / dt
                speed = math.hypot(vx, vy)
                if speed > p.max_speed_mps:
                    vx, vy = vx * p.max_speed_mps / speed, vy * p.max_speed_mps / speed
                a = p.smoothing
                tr.vx_mps = (1 - a) * tr.vx_mps + a * vx
                tr.vy_mps = (1 - a) * tr.vy_mps + a * vy
                tr.x_m, tr.y_m = float(centres[si, 0]), float(centres[si, 1])
                tr.radius_m = max(float(half[si]), 0.05)
                tr.t = t
                tr.hits += 1
        for si in range(len(centres)):
            if si not in matched_segs:
                self.tracks.append(Track(float(centres[si, 0]), float(centres[si, 1]), 0.0, 0.0,
                                         max(float(half[si]), 0.05), t))
        return self.tracks

    def moving(self) -> list[Track]:
        """Tracks confirmed as moving."""
        p = self.params
        return [tr for tr in self.tracks if tr.hits >= p.min_hits and tr.speed_mps >= p.min_speed_mps]

    def predicted_points(self, spacing_m: float) -> FloatArray:
        """Points covering where the moving tracks will be over the horizon (disks along their motion)."""
        p = self.params
        out = []
        taus = np.arange(p.step_s, p.horizon_s + 1e-9, p.step_s)
        for tr in self.moving():
            r = tr.radius_m
            k = max(int(r / spacing_m), 1)
            offs = np.arange(-k, k + 1) * spacing_m
            ox, oy = np.meshgrid(offs, offs)
            disk = np.hypot(ox, oy) <= r + 1e-9
            ox, oy = ox[disk], oy[disk]
            cx = tr.x_m + tr.vx_mps * taus
            cy = tr.y_m + tr.vy_mps * taus
            out.append(np.column_stack([(cx[:, None] + ox[None, :]).ravel(), (cy[:, None] + oy[None, :]).ravel()]))
        return np.concatenate(out) if out else np.zeros((0, 2))
