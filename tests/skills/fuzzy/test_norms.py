"""Norms and hedges: contract tests over every registered operator plus hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atemr.skills.fuzzy.norms import HEDGES, SNORMS, TNORMS

unit = st.floats(min_value=0.0, max_value=1.0)


@pytest.mark.parametrize("name", list(TNORMS))
@given(a=unit, b=unit)
def test_every_tnorm_is_a_tnorm(name: str, a: float, b: float) -> None:
    t = TNORMS.get(name)
    v = float(t(np.array(a), np.array(b)))
    assert float(t(np.array(a), np.array(1.0))) == pytest.approx(a)
    assert float(t(np.array(a), np.array(0.0))) == pytest.approx(0.0)
    assert v == pytest.approx(float(t(np.array(b), np.array(a))))
    assert -1e-12 <= v <= min(a, b) + 1e-12


@pytest.mark.parametrize("name", list(SNORMS))
@given(a=unit, b=unit)
def test_every_snorm_is_an_snorm(name: str, a: float, b: float) -> None:
    s = SNORMS.get(name)
    v = float(s(np.array(a), np.array(b)))
    assert float(s(np.array(a), np.array(0.0))) == pytest.approx(a)
    assert v == pytest.approx(float(s(np.array(b), np.array(a))))
    # 1e-9, not 1e-12: HamacherSum's (a + b - 2ab) / (1 - ab) cancels near (1, 1) (fuzzylite computes it the
    # same way): S(1.0, 0.99999) comes out 1.1e-11 below 1.
    assert v >= max(a, b) - 1e-9


@pytest.mark.parametrize(
    ("name", "a", "b", "expected"),
    [("Minimum", 0.3, 0.6, 0.3), ("AlgebraicProduct", 0.5, 0.6, 0.3), ("BoundedDifference", 0.5, 0.6, 0.1),
     ("EinsteinProduct", 0.5, 0.5, 0.25 / 1.25), ("HamacherProduct", 0.0, 0.0, 0.0),
     ("NilpotentMinimum", 0.3, 0.6, 0.0)],
)
def test_tnorm_values(name: str, a: float, b: float, expected: float) -> None:
    assert float(TNORMS.get(name)(np.array(a), np.array(b))) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("name", "a", "b", "expected"),
    [("Maximum", 0.3, 0.6, 0.6), ("AlgebraicSum", 0.5, 0.5, 0.75), ("BoundedSum", 0.5, 0.6, 1.0),
     ("UnboundedSum", 0.5, 0.6, 1.1), ("EinsteinSum", 0.5, 0.5, 0.8), ("NilpotentMaximum", 0.5, 0.6, 1.0)],
)
def test_snorm_values(name: str, a: float, b: float, expected: float) -> None:
    assert float(SNORMS.get(name)(np.array(a), np.array(b))) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("name", "x", "expected"),
    [("not", 0.2, 0.8), ("very", 0.5, 0.25), ("somewhat", 0.25, 0.5), ("extremely", 0.25, 0.125),
     ("extremely", 0.75, 0.875), ("seldom", 0.5, 0.5)],
)
def test_hedges(name: str, x: float, expected: float) -> None:
    assert float(HEDGES.get(name)(np.array(x))) == pytest.approx(expected)
