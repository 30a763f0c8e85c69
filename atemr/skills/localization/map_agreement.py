"""How well a scan agrees with the map at a pose, counted honestly beam by beam.

A point close to *some* wall is not evidence that the pose is right: seen from another room, most end
points of a scan still land near a wall, but the beams that lead to them cross walls on the way. So every
beam of the scan, under the pose, is one of three things:

* **hit**: the beam ends on mapped structure (within ``hit_tolerance_m`` of an occupied cell) and crosses
  no occupied cell before it (``through_tolerance_m`` short of its end, for the noise and the cell size);
* **through**: the beam crosses an occupied cell on its way: the scan sees through a mapped wall, which
  contradicts the pose (or the map changed there: a door open that was shut when it was mapped);
* **unexplained**: the beam ends in free or unknown space, away from mapped structure: something the map
  does not know stands there (a person, a pet, a new chair), or the pose is wrong.

Two shares follow (`ScanAgreement`):

* ``agreement = hits / beams``: the share of the scan on the map, the strict number global localization
  decides by (a wrong pose cannot hide its unexplained points);
* ``structure_agreement = hits / (hits + through)``: among the beams that reach mapped structure, the share
  that meets it where the map says. Unmapped and moving obstacles only ever shorten beams, so they leave
  this share alone: it is what says whether a localized robot is lost.

The beams are walked along their length on the map's distance table (`LikelihoodField.crossings`: sphere
tracing, never a step over a wall), for all poses and beams at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.skills.localization.geometry import FloatArray
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.scan import evenly_spread

HIT, THROUGH, UNEXPLAINED = 0, 1, 2


@dataclass(frozen=True)
class AgreementParams:
    """What counts as on the map."""

    #: A beam's end within this of an occupied cell is on mapped structure.
    hit_tolerance_m: float = 0.15
    #: A beam crosses a wall only if it meets an occupied cell more than this before its end.
    through_tolerance_m: float = 0.2
    #: Beams checked per scan, evenly spread over the valid ones (the cost grows with their number).
    max_beams: int = 120

    def __post_init__(self) -> None:
        for name in ("hit_tolerance_m", "through_tolerance_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.{name}")
        if self.max_beams < 1:
            raise ConfigError(f"must be >= 1, got {self.max_beams!r}", path="localization.agreement_beams")


@dataclass(frozen=True)
class ScanAgreement:
    """Beam counts of one scan under each of ``N`` poses (arrays of length ``N``)."""

    hits: NDArray[np.int_]
    through: NDArray[np.int_]
    unexplained: NDArray[np.int_]

    @property
    def beams(self) -> NDArray[np.int_]:
        return self.hits + self.through + self.unexplained

    @property
    def agreement(self) -> FloatArray:
        """``hits / beams`` (0 for an empty scan): the share of the scan on the map."""
        return self.hits / np.maximum(self.beams, 1)

    @property
    def structure_agreement(self) -> FloatArray:
        """``hits / (hits + through)`` (0 when no beam reaches mapped structure): unmapped obstacles left out."""
        return self.hits / np.maximum(self.hits + self.through, 1)

    @property
    def reach(self) -> FloatArray:
        """``(hits + through) / beams``: the share of beams that reach mapped structure (or pass through it)."""
        return (self.hits + self.through) / np.maximum(self.beams, 1)

    def at(self, i: int) -> ScanAgreement:
        """The counts under pose ``i`` alone."""
        return ScanAgreement(self.hits[i:i + 1], self.through[i:i + 1], self.unexplained[i:i + 1])


class MapAgreement:
    """Classifies scan beams against one map (its `LikelihoodField`'s distance table)."""

    def __init__(self, field: LikelihoodField, params: AgreementParams | None = None) -> None:
        self.field = field
        self.params = params or AgreementParams()

    def _thinned(self, points: FloatArray) -> FloatArray:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        pts = pts[np.isfinite(pts).all(axis=1)]
        if pts.shape[0] > self.params.max_beams:
            pts = pts[evenly_spread(pts.shape[0], self.params.max_beams)]
        return pts

    def classify(self, poses: FloatArray, points: FloatArray, sensor_xy: tuple[float, float] = (0.0, 0.0)
                 ) -> NDArray[np.int8]:
        """`HIT`, `THROUGH` or `UNEXPLAINED` for every pose ``(N, 3)`` and base-frame point ``(M, 2)``: ``(N, M)``.

        ``sensor_xy``: where the beams start in the base frame (`atemr.skills.localization.scan.sensor_origin`).
        Every point is used; `measure` thins the scan first.
        """
        p = self.params
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        n = np.asarray(poses).reshape(-1, 3).shape[0]
        if pts.shape[0] == 0:
            return np.zeros((n, 0), dtype=np.int8)
        through = self.field.crossings(poses, sensor_xy, pts, p.through_tolerance_m)
        near = self.field.distances(poses, pts) <= p.hit_tolerance_m
        return np.where(through, THROUGH, np.where(near, HIT, UNEXPLAINED)).astype(np.int8)

    def open_clear(self, poses: FloatArray, ends: FloatArray, sensor_xy: tuple[float, float] = (0.0, 0.0)
                   ) -> NDArray[np.bool_]:
        """For the beams that met nothing within the lidar's range (`scan.open_ray_ends`): whether each passes no
        occupied cell up to its end, under every pose: ``(N, F)``. A pose that puts a wall across an open beam is
        contradicted by it as a beam through a wall contradicts it."""
        ends = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
        return ~self.field.crossings(poses, sensor_xy, ends, 0.0)

    def measure(self, poses: FloatArray, points: FloatArray, sensor_xy: tuple[float, float] = (0.0, 0.0)
                ) -> ScanAgreement:
        """Beam counts of the scan under every pose (the scan thinned to ``max_beams`` evenly spread beams)."""
        kinds = self.classify(poses, self._thinned(points), sensor_xy)
        return ScanAgreement((kinds == HIT).sum(axis=1), (kinds == THROUGH).sum(axis=1),
                             (kinds == UNEXPLAINED).sum(axis=1))


__all__ = ["HIT", "THROUGH", "UNEXPLAINED", "AgreementParams", "MapAgreement", "ScanAgreement"]
