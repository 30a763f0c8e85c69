"""Membership functions (terms) of fuzzy variables, vectorised over any array shape.

The shapes and parameter orders are fuzzylite's, so a `.fll` line ``term: NEAR Ramp 0.6 0.2`` and the
YAML ``NEAR: Ramp 0.6 0.2`` build the same object. Where scikit-fuzzy has the same function the formula
is identical (``trimf``, ``trapmf``, ``gaussmf``, ``gbellmf``, ``sigmf``, ``zmf``, ``smf``; the tests
check it), but these versions take arrays of any shape, handle infinite vertices and NaN inputs like
fuzzylite does, and accept an optional height (the last parameter).

Monotonic terms (Ramp, Sigmoid, SShape, ZShape, Concave) also have `Term.tsukamoto`, the inverse used by
Tsukamoto inference: the crisp value at which the term reaches a rule's activation degree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from atemr.errors import ConfigError
from atemr.registry import Registry

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Term:
    """A named membership function. ``params`` are the shape's numbers in fuzzylite order."""

    name: str
    params: tuple[float, ...]
    height: float = 1.0

    #: Names of the shape parameters, in order (the optional height comes after them).
    PARAMS: ClassVar[tuple[str, ...]] = ()
    #: Whether a trailing parameter may give the height of the term.
    HAS_HEIGHT: ClassVar[bool] = True
    #: Whether the term has an inverse usable by Tsukamoto inference.
    MONOTONIC: ClassVar[bool] = False

    @property
    def kind(self) -> str:
        """The shape's name as written in YAML and `.fll` files (``Triangle``, ``Ramp``, ...)."""
        return type(self).__name__

    def membership(self, x: ArrayLike) -> Array:
        """μ(x), same shape as ``x``; NaN where x is NaN."""
        xa = np.asarray(x, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            mu = self.height * self._shape(xa)
        if self._nan_at_nan():
            return np.asarray(mu)
        return np.where(np.isnan(xa), np.nan, mu)

    def tsukamoto(self, y: ArrayLike) -> Array:
        """The crisp x at which this monotonic term reaches degree ``y`` (only for MONOTONIC terms)."""
        raise ConfigError(f"term '{self.name}' ({self.kind}) is not monotonic: it cannot be a Tsukamoto output")

    def validate(self) -> None:
        """Refuse shapes that are not functions (vertices out of order, zero widths); raises `ConfigError`."""

    def _shape(self, x: Array) -> Array:
        raise NotImplementedError

    def _nan_at_nan(self) -> bool:
        """Whether `_shape` is NaN wherever x is NaN already, so `membership` need not mask NaN inputs."""
        return False

    def describe(self) -> str:
        """The term as a `.fll`-style line fragment: ``NEAR Ramp 0.6 0.2``."""
        nums = [*self.params, *([self.height] if self.HAS_HEIGHT and self.height != 1.0 else [])]
        return f"{self.name} {self.kind} {' '.join(f'{v:g}' for v in nums)}".rstrip()


TERMS: Registry[type[Term]] = Registry("fuzzy_term")


def build_term(kind: str, name: str, values: list[float]) -> Term:
    """Build a term of shape ``kind`` from its numbers; wrong counts and bad shapes raise `ConfigError`."""
    if kind not in TERMS:
        raise ConfigError(TERMS.unknown_message(kind))
    cls = TERMS.get(kind)
    if any(math.isnan(v) for v in values):
        raise ConfigError(f"term '{name}' ({kind}): parameters must be numbers, got NaN")
    n = len(cls.PARAMS)
    if cls is Linear:
        return Linear(name, tuple(values), 1.0)
    allowed = f"{n}" + (f" or {n + 1} (the last being the height)" if cls.HAS_HEIGHT else "")
    if len(values) < n or len(values) > n + (1 if cls.HAS_HEIGHT else 0):
        raise ConfigError(
            f"term '{name}' ({kind}) takes {allowed} parameters ({', '.join(cls.PARAMS)}), got {len(values)}"
        )
    height = values[n] if len(values) > n else 1.0
    term = cls(name, tuple(values[:n]), height)
    term.validate()
    return term


def _check(term: Term, ok: bool, why: str) -> None:
    if not ok:
        raise ConfigError(f"term '{term.name}' ({term.kind} {' '.join(f'{v:g}' for v in term.params)}): {why}")


@TERMS.register("Triangle")
@dataclass(frozen=True)
class Triangle(Term):
    """Rises from a to 1 at b, falls to 0 at c (skfuzzy ``trimf([a, b, c])``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("a", "b", "c")

    def validate(self) -> None:
        a, b, c = self.params
        _check(self, a <= b <= c, "vertices must satisfy a <= b <= c")

    def _shape(self, x: Array) -> Array:
        a, b, c = self.params
        rise = 1.0 if a == -math.inf else (x - a) / (b - a)
        fall = 1.0 if c == math.inf else (c - x) / (c - b)
        return np.select([(x < a) | (x > c), x == b, x < b], [0.0, 1.0, rise], fall)


@TERMS.register("Trapezoid")
@dataclass(frozen=True)
class Trapezoid(Term):
    """0 before a, rises to 1 at b, flat to c, falls to 0 at d (skfuzzy ``trapmf([a, b, c, d])``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("a", "b", "c", "d")

    def validate(self) -> None:
        a, b, c, d = self.params
        _check(self, a <= b <= c <= d, "vertices must satisfy a <= b <= c <= d")

    def _shape(self, x: Array) -> Array:
        a, b, c, d = self.params
        rise = 1.0 if a == -math.inf else (x - a) / (b - a)
        fall = 1.0 if d == math.inf else (d - x) / (d - c)
        tail = 1.0 if d == math.inf else 0.0
        return np.select([(x < a) | (x > d), x < b, x <= c, x < d], [0.0, rise, 1.0, fall], tail)


@TERMS.register("Rectangle")
@dataclass(frozen=True)
class Rectangle(Term):
    """1 on [start, end], 0 elsewhere."""

    PARAMS: ClassVar[tuple[str, ...]] = ("start", "end")

    def validate(self) -> None:
        _check(self, self.params[0] <= self.params[1], "start must not exceed end")

    def _shape(self, x: Array) -> Array:
        s, e = self.params
        return ((x >= s) & (x <= e)).astype(np.float64)


@TERMS.register("Ramp")
@dataclass(frozen=True)
class Ramp(Term):
    """0 at start, 1 at end, linear between; start > end makes a falling ramp (NEAR-style terms)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("start", "end")
    MONOTONIC: ClassVar[bool] = True

    def validate(self) -> None:
        _check(self, self.params[0] != self.params[1], "start and end must differ")

    def _shape(self, x: Array) -> Array:
        s, e = self.params
        if not self._nan_at_nan():  # an infinite end: the rise is inf/inf, keep the explicit cases
            if s < e:
                return np.select([x <= s, x >= e], [0.0, 1.0], (x - s) / (e - s))
            return np.select([x >= s, x <= e], [0.0, 1.0], (s - x) / (s - e))
        # the same numbers as the select above: the quotient is <= 0 exactly where x is at or before the
        # start and >= 1 exactly where x is at or past the end (rounding is monotonic); NaN stays NaN
        t = (x - s) / (e - s) if s < e else (s - x) / (s - e)
        return np.minimum(np.maximum(t, 0.0), 1.0)

    def _nan_at_nan(self) -> bool:
        return math.isfinite(self.params[0]) and math.isfinite(self.params[1])

    def tsukamoto(self, y: ArrayLike) -> Array:
        s, e = self.params
        return s + (e - s) * np.asarray(y, dtype=np.float64) / self.height


@TERMS.register("Gaussian")
@dataclass(frozen=True)
class Gaussian(Term):
    """exp(−(x − mean)² / 2σ²) (skfuzzy ``gaussmf(x, mean, sigma)``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("mean", "standard_deviation")

    def validate(self) -> None:
        _check(self, self.params[1] > 0, "standard deviation must be positive")

    def _shape(self, x: Array) -> Array:
        m, sd = self.params
        return np.exp(-np.square(x - m) / (2.0 * sd * sd))


@TERMS.register("Bell")
@dataclass(frozen=True)
class Bell(Term):
    """1 / (1 + |(x − center)/width|^(2·slope)) (skfuzzy ``gbellmf(x, width, slope, center)``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("center", "width", "slope")

    def validate(self) -> None:
        _check(self, self.params[1] != 0, "width must not be zero")

    def _shape(self, x: Array) -> Array:
        c, w, s = self.params
        return 1.0 / (1.0 + np.power(np.abs((x - c) / w), 2.0 * s))


@TERMS.register("Sigmoid")
@dataclass(frozen=True)
class Sigmoid(Term):
    """1 / (1 + exp(−slope·(x − inflection))) (skfuzzy ``sigmf(x, inflection, slope)``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("inflection", "slope")
    MONOTONIC: ClassVar[bool] = True

    def _shape(self, x: Array) -> Array:
        i, s = self.params
        return 1.0 / (1.0 + np.exp(-s * (x - i)))

    def tsukamoto(self, y: ArrayLike) -> Array:
        i, s = self.params
        with np.errstate(divide="ignore", invalid="ignore"):
            return i + np.log(self.height / np.asarray(y, dtype=np.float64) - 1.0) / -s


@TERMS.register("SShape")
@dataclass(frozen=True)
class SShape(Term):
    """Smooth rise from 0 at start to 1 at end (skfuzzy ``smf(x, start, end)``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("start", "end")
    MONOTONIC: ClassVar[bool] = True

    def validate(self) -> None:
        _check(self, self.params[0] < self.params[1], "start must be below end")

    def _shape(self, x: Array) -> Array:
        s, e = self.params
        return np.select(
            [x <= s, x <= 0.5 * (s + e), x < e],
            [0.0, 2.0 * np.square((x - s) / (e - s)), 1.0 - 2.0 * np.square((x - e) / (e - s))],
            1.0,
        )

    def tsukamoto(self, y: ArrayLike) -> Array:
        s, e = self.params
        h = self.height
        ya = np.asarray(y, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            return np.where(ya <= h / 2, s + (e - s) * np.sqrt(ya / (2 * h)), e - (e - s) * np.sqrt((h - ya) / (2 * h)))


@TERMS.register("ZShape")
@dataclass(frozen=True)
class ZShape(Term):
    """Smooth fall from 1 at start to 0 at end (skfuzzy ``zmf(x, start, end)``)."""

    PARAMS: ClassVar[tuple[str, ...]] = ("start", "end")
    MONOTONIC: ClassVar[bool] = True

    def validate(self) -> None:
        _check(self, self.params[0] < self.params[1], "start must be below end")

    def _shape(self, x: Array) -> Array:
        s, e = self.params
        return np.select(
            [x <= s, x <= 0.5 * (s + e), x < e],
            [1.0, 1.0 - 2.0 * np.square((x - s) / (e - s)), 2.0 * np.square((x - e) / (e - s))],
            0.0,
        )

    def tsukamoto(self, y: ArrayLike) -> Array:
        s, e = self.params
        h = self.height
        ya = np.asarray(y, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            return np.where(ya <= h / 2, e - (e - s) * np.sqrt(ya / (2 * h)), s + (e - s) * np.sqrt((h - ya) / (2 * h)))


@TERMS.register("Concave")
@dataclass(frozen=True)
class Concave(Term):
    """(e − i)/(2e − i − x) rising to 1 at end (inflection <= end), mirrored when inflection > end."""

    PARAMS: ClassVar[tuple[str, ...]] = ("inflection", "end")
    MONOTONIC: ClassVar[bool] = True

    def _shape(self, x: Array) -> Array:
        i, e = self.params
        if i <= e:
            return np.where(x < e, (e - i) / (2.0 * e - i - x), 1.0)
        return np.where(x > e, (i - e) / (i - 2.0 * e + x), 1.0)

    def tsukamoto(self, y: ArrayLike) -> Array:
        i, e = self.params
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.height * (i - e) / np.asarray(y, dtype=np.float64) + 2.0 * e - i


@TERMS.register("Constant")
@dataclass(frozen=True)
class Constant(Term):
    """A Takagi-Sugeno output value k, whatever the inputs."""

    PARAMS: ClassVar[tuple[str, ...]] = ("value",)
    HAS_HEIGHT: ClassVar[bool] = False

    def _shape(self, x: Array) -> Array:
        return np.full_like(x, self.params[0])


@TERMS.register("Linear")
@dataclass(frozen=True)
class Linear(Term):
    """A Takagi-Sugeno output c₁·x₁ + … + cₙ·xₙ [+ k] over the engine's inputs, in their order."""

    PARAMS: ClassVar[tuple[str, ...]] = ("coefficients",)
    HAS_HEIGHT: ClassVar[bool] = False

    def evaluate(self, inputs: Array) -> Array:
        """The value for each row of ``inputs`` (shape (N, n_inputs))."""
        n = inputs.shape[1]
        c = np.asarray(self.params, dtype=np.float64)
        if len(c) not in (n, n + 1):
            raise ConfigError(f"term '{self.name}' (Linear) has {len(c)} coefficients; the engine has {n} inputs")
        out = inputs @ c[:n]
        return out + c[n] if len(c) == n + 1 else out

    def _shape(self, x: Array) -> Array:
        raise ConfigError(f"term '{self.name}' (Linear) depends on the inputs: only Takagi-Sugeno outputs use it")

    def describe(self) -> str:
        return f"{self.name} Linear {' '.join(f'{v:g}' for v in self.params)}"
