"""T-norms, S-norms and hedges, vectorised over numpy arrays.

Names follow fuzzylite (``Minimum``, ``AlgebraicProduct``, ``Maximum``, ...) so a `.fll` file and a YAML
engine name the same operator the same way. Every operator is a pure function of two broadcastable
arrays; the engine reduces over rules with them, never over input rows.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from atemr.registry import Registry

Array = NDArray[np.float64]
Norm = Callable[[Array, Array], Array]
Hedge = Callable[[Array], Array]

#: Conjunction and implication operators: T(a, 1) = a, T(a, 0) = 0, monotone in each argument.
TNORMS: Registry[Norm] = Registry("fuzzy_tnorm")
#: Disjunction and aggregation operators: S(a, 0) = a, S(a, 1) = 1.
SNORMS: Registry[Norm] = Registry("fuzzy_snorm")
#: Linguistic hedges applied to a membership degree (``FR is very NEAR``).
HEDGES: Registry[Hedge] = Registry("fuzzy_hedge")


def _f(x: Array | float) -> Array:
    return np.asarray(x, dtype=np.float64)


@TNORMS.register("Minimum")
def minimum(a: Array, b: Array) -> Array:
    """min(a, b): classic Mamdani conjunction and implication (clips the output term)."""
    return np.minimum(a, b)


@TNORMS.register("AlgebraicProduct")
def algebraic_product(a: Array, b: Array) -> Array:
    """a·b: Larsen implication (scales the output term instead of clipping it)."""
    return _f(a) * b


@TNORMS.register("BoundedDifference")
def bounded_difference(a: Array, b: Array) -> Array:
    """max(0, a + b − 1), the Łukasiewicz t-norm."""
    return np.maximum(0.0, _f(a) + b - 1.0)


@TNORMS.register("DrasticProduct")
def drastic_product(a: Array, b: Array) -> Array:
    """min(a, b) when max(a, b) = 1, otherwise 0."""
    a, b = np.broadcast_arrays(_f(a), _f(b))
    return np.where(np.maximum(a, b) == 1.0, np.minimum(a, b), 0.0)


@TNORMS.register("EinsteinProduct")
def einstein_product(a: Array, b: Array) -> Array:
    """(a·b) / (2 − (a + b − a·b))."""
    a, b = _f(a), _f(b)
    return (a * b) / (2.0 - (a + b - a * b))


@TNORMS.register("HamacherProduct")
def hamacher_product(a: Array, b: Array) -> Array:
    """(a·b) / (a + b − a·b), and 0 where a + b = 0 (fuzzylite's convention)."""
    a, b = np.broadcast_arrays(_f(a), _f(b))
    den = a + b - a * b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(a + b != 0.0, (a * b) / np.where(den == 0.0, 1.0, den), 0.0)


@TNORMS.register("NilpotentMinimum")
def nilpotent_minimum(a: Array, b: Array) -> Array:
    """min(a, b) when a + b > 1, otherwise 0."""
    a, b = np.broadcast_arrays(_f(a), _f(b))
    return np.where(a + b > 1.0, np.minimum(a, b), 0.0)


@SNORMS.register("Maximum")
def maximum(a: Array, b: Array) -> Array:
    """max(a, b): the usual aggregation and disjunction."""
    return np.maximum(a, b)


@SNORMS.register("AlgebraicSum")
def algebraic_sum(a: Array, b: Array) -> Array:
    """a + b − a·b (probabilistic or)."""
    a, b = _f(a), _f(b)
    return a + b - a * b


@SNORMS.register("BoundedSum")
def bounded_sum(a: Array, b: Array) -> Array:
    """min(1, a + b)."""
    return np.minimum(1.0, _f(a) + b)


@SNORMS.register("UnboundedSum")
def unbounded_sum(a: Array, b: Array) -> Array:
    """a + b: fuzzylite's default for grouping the weights of a weighted defuzzifier."""
    return _f(a) + b


@SNORMS.register("DrasticSum")
def drastic_sum(a: Array, b: Array) -> Array:
    """max(a, b) when min(a, b) = 0, otherwise 1."""
    a, b = np.broadcast_arrays(_f(a), _f(b))
    return np.where(np.minimum(a, b) == 0.0, np.maximum(a, b), 1.0)


@SNORMS.register("EinsteinSum")
def einstein_sum(a: Array, b: Array) -> Array:
    """(a + b) / (1 + a·b)."""
    a, b = _f(a), _f(b)
    return (a + b) / (1.0 + a * b)


@SNORMS.register("HamacherSum")
def hamacher_sum(a: Array, b: Array) -> Array:
    """(a + b − 2ab) / (1 − ab), and 1 where a·b = 1."""
    a, b = np.broadcast_arrays(_f(a), _f(b))
    den = 1.0 - a * b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den != 0.0, (a + b - 2.0 * a * b) / np.where(den == 0.0, 1.0, den), 1.0)


@SNORMS.register("NilpotentMaximum")
def nilpotent_maximum(a: Array, b: Array) -> Array:
    """max(a, b) when a + b < 1, otherwise 1."""
    a, b = np.broadcast_arrays(_f(a), _f(b))
    return np.where(a + b < 1.0, np.maximum(a, b), 1.0)


@HEDGES.register("not")
def hedge_not(x: Array) -> Array:
    """1 − x."""
    return 1.0 - _f(x)


@HEDGES.register("very")
def hedge_very(x: Array) -> Array:
    """x², concentrates the term."""
    return np.square(_f(x))


@HEDGES.register("somewhat")
def hedge_somewhat(x: Array) -> Array:
    """√x, dilates the term."""
    return np.sqrt(_f(x))


@HEDGES.register("extremely")
def hedge_extremely(x: Array) -> Array:
    """2x² below 0.5, 1 − 2(1 − x)² above (contrast intensification)."""
    x = _f(x)
    return np.where(x <= 0.5, 2.0 * x * x, 1.0 - 2.0 * np.square(1.0 - x))


@HEDGES.register("seldom")
def hedge_seldom(x: Array) -> Array:
    """√(x/2) below 0.5, 1 − √((1 − x)/2) above."""
    x = _f(x)
    with np.errstate(invalid="ignore"):
        return np.where(x <= 0.5, np.sqrt(0.5 * x), 1.0 - np.sqrt(0.5 * (1.0 - x)))
