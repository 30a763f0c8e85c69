"""Defuzzifiers: turn each row's fuzzy output into one crisp value, vectorised over rows.

Two families, as in fuzzylite:

* integral defuzzifiers (Centroid, Bisector, MeanOfMaximum, SmallestOfMaximum, LargestOfMaximum) work on
  the aggregated membership sampled at ``resolution`` midpoints of the output range,
  ``x_i = min + (i + 0.5)·(max − min)/resolution`` (fuzzylite's midpoint rectangle rule; default
  resolution 1000 like fuzzylite 7). Input: array (rows, resolution).
* weighted defuzzifiers (WeightedAverage, WeightedSum) work on the activation degree ``w`` of each
  output term and the term's value ``z`` (Takagi-Sugeno: the constant or linear function; Tsukamoto: the
  crisp value at which the monotonic term reaches ``w``).

A row where no rule fired gets the output's default value (NaN unless the engine says otherwise): that is
decided by the engine, not here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.registry import Registry

Array = NDArray[np.float64]

DEFAULT_RESOLUTION = 1000


@dataclass(frozen=True)
class Defuzzifier:
    """Base of all defuzzifiers; ``describe()`` gives the `.fll` spelling (``Centroid 200``)."""

    INTEGRAL: ClassVar[bool] = False

    @property
    def kind(self) -> str:
        """The name used in YAML and `.fll` files."""
        return type(self).__name__

    def describe(self) -> str:
        """The defuzzifier as written in an engine file."""
        return self.kind


@dataclass(frozen=True)
class IntegralDefuzzifier(Defuzzifier):
    """Integrates the aggregated output over ``resolution`` midpoint samples of the range."""

    resolution: int = DEFAULT_RESOLUTION
    INTEGRAL: ClassVar[bool] = True

    def samples(self, minimum: float, maximum: float) -> Array:
        """The x positions the aggregated membership is evaluated at (midpoints of equal cells)."""
        dx = (maximum - minimum) / self.resolution
        return minimum + (np.arange(self.resolution, dtype=np.float64) + 0.5) * dx

    def reduce(self, x: Array, y: Array) -> Array:
        """Crisp value per row from ``y`` (rows, resolution) sampled at ``x`` (resolution,)."""
        raise NotImplementedError

    def describe(self) -> str:
        return f"{self.kind} {self.resolution}"


@dataclass(frozen=True)
class Centroid(IntegralDefuzzifier):
    """Σ x·μ(x) / Σ μ(x): the centre of gravity (NaN when the area is zero, like fuzzylite)."""

    def reduce(self, x: Array, y: Array) -> Array:
        with np.errstate(divide="ignore", invalid="ignore"):
            return (y @ x) / y.sum(axis=1)


@dataclass(frozen=True)
class Bisector(IntegralDefuzzifier):
    """The sample that best splits the area in two halves, computed as fuzzylite computes it.

    The cumulative area at each midpoint sample counts that sample's whole cell; normalised by the total,
    the sample(s) whose cumulative share is closest to one half win, and ties (a flat stretch of zero
    membership around the half) give the mean of their x. So the answer is always a sample or the mean of
    some, at most half a cell from the exact bisector, and an engine imported from ``.fll`` gives
    fuzzylite's numbers. NaN when the area is zero.
    """

    def reduce(self, x: Array, y: Array) -> Array:
        area = np.cumsum(y, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            distance = np.abs(area / area[:, -1:] - 0.5)  # rows with no area: all NaN, so nothing is closest
            closest = distance == np.min(distance, axis=1, keepdims=True)
            count = closest.sum(axis=1)
            return np.where(count > 0, (closest * x).sum(axis=1) / count, np.nan)


def _maxima(y: Array) -> NDArray[np.bool_]:
    return (y > 0) & (y == y.max(axis=1, keepdims=True))


@dataclass(frozen=True)
class MeanOfMaximum(IntegralDefuzzifier):
    """Mean of the x samples where the membership is at its (positive) maximum."""

    def reduce(self, x: Array, y: Array) -> Array:
        m = _maxima(y)
        count = m.sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(count > 0, (m * x).sum(axis=1) / count, np.nan)


@dataclass(frozen=True)
class SmallestOfMaximum(IntegralDefuzzifier):
    """Smallest x sample where the membership is at its (positive) maximum."""

    def reduce(self, x: Array, y: Array) -> Array:
        m = _maxima(y)
        return np.where(m.any(axis=1), x[np.argmax(m, axis=1)], np.nan)


@dataclass(frozen=True)
class LargestOfMaximum(IntegralDefuzzifier):
    """Largest x sample where the membership is at its (positive) maximum."""

    def reduce(self, x: Array, y: Array) -> Array:
        m = _maxima(y)
        last = m.shape[1] - 1 - np.argmax(m[:, ::-1], axis=1)
        return np.where(m.any(axis=1), x[last], np.nan)


WEIGHTED_TYPES = ("Automatic", "TakagiSugeno", "Tsukamoto")


@dataclass(frozen=True)
class WeightedDefuzzifier(Defuzzifier):
    """Combines (w, z) pairs; ``type`` Automatic infers TakagiSugeno or Tsukamoto from the output terms."""

    type: str = "Automatic"

    def combine(self, w: Array, z: Array, present: NDArray[np.bool_]) -> Array:
        """Crisp value per row from degrees and values of shape (rows, terms); absent terms are ignored."""
        raise NotImplementedError

    def describe(self) -> str:
        return f"{self.kind} {self.type}"


def _weighted_sum(w: Array, z: Array, present: NDArray[np.bool_]) -> Array:
    with np.errstate(invalid="ignore", over="ignore"):
        return np.where(present, w * z, 0.0).sum(axis=1)


@dataclass(frozen=True)
class WeightedAverage(WeightedDefuzzifier):
    """Σ w·z / Σ w over the output terms that fired."""

    def combine(self, w: Array, z: Array, present: NDArray[np.bool_]) -> Array:
        with np.errstate(divide="ignore", invalid="ignore"):
            return _weighted_sum(w, z, present) / np.where(present, w, 0.0).sum(axis=1)


@dataclass(frozen=True)
class WeightedSum(WeightedDefuzzifier):
    """Σ w·z over the output terms that fired."""

    def combine(self, w: Array, z: Array, present: NDArray[np.bool_]) -> Array:
        return _weighted_sum(w, z, present)


DEFUZZIFIERS: Registry[type[Defuzzifier]] = Registry("fuzzy_defuzzifier")
for _cls in (Centroid, Bisector, MeanOfMaximum, SmallestOfMaximum, LargestOfMaximum, WeightedAverage, WeightedSum):
    DEFUZZIFIERS.add(_cls.__name__, _cls)


def build_defuzzifier(kind: str, parameter: str | int | None = None) -> Defuzzifier:
    """Build a defuzzifier from its name and optional parameter (resolution or weighted type)."""
    if kind not in DEFUZZIFIERS:
        raise ConfigError(DEFUZZIFIERS.unknown_message(kind))
    cls = DEFUZZIFIERS.get(kind)
    if issubclass(cls, IntegralDefuzzifier):
        if parameter is None or parameter == "":
            return cls()
        try:
            resolution = int(parameter)
        except (TypeError, ValueError):
            raise ConfigError(f"{kind}: resolution must be an integer, got {parameter!r}") from None
        if not 2 <= resolution <= 1_000_000:
            raise ConfigError(f"{kind}: resolution must be within [2, 1000000], got {resolution}")
        return cls(resolution)
    if issubclass(cls, WeightedDefuzzifier):
        if parameter is None or parameter == "":
            return cls()
        if parameter not in WEIGHTED_TYPES:
            raise ConfigError(f"{kind}: type must be one of {', '.join(WEIGHTED_TYPES)}, got {parameter!r}")
        return cls(str(parameter))
    return cls()  # pragma: no cover - every registered class is one of the two families
