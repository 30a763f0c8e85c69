"""Membership functions: hand-computed values, agreement with scikit-fuzzy, Tsukamoto inverses."""

from __future__ import annotations

import math

import numpy as np
import pytest
import skfuzzy as fuzz
from hypothesis import given
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.skills.fuzzy.terms import TERMS, build_term

X = np.linspace(-2.0, 12.0, 1401)


@pytest.mark.parametrize(
    ("kind", "params", "x", "expected"),
    [
        ("Triangle", [0, 5, 10], [0, 2.5, 5, 7.5, 10, 11], [0, 0.5, 1, 0.5, 0, 0]),
        ("Trapezoid", [0, 0, 1, 3], [0, 0.5, 1, 2, 3, 4], [1, 1, 1, 0.5, 0, 0]),
        ("Trapezoid", [7, 9, 10, 10], [6, 8, 9.5, 10], [0, 0.5, 1, 1]),
        ("Ramp", [1.0, 0.4], [0.0, 0.4, 0.7, 1.0, 1.2], [1, 1, 0.5, 0, 0]),
        ("Ramp", [0.4, 1.0], [0.0, 0.7, 1.2], [0, 0.5, 1]),
        ("Rectangle", [1, 2], [0.5, 1, 1.5, 2, 2.5], [0, 1, 1, 1, 0]),
        ("Gaussian", [5, 1.5], [5, 6.5], [1, math.exp(-0.5)]),
        ("Bell", [0, 5, 3], [0, 5, 10], [1, 0.5, 1 / 65]),
        ("Sigmoid", [0.5, 30], [0.5], [0.5]),
        ("SShape", [0, 1], [0, 0.25, 0.5, 0.75, 1], [0, 0.125, 0.5, 0.875, 1]),
        ("ZShape", [0, 1], [0, 0.25, 0.5, 0.75, 1], [1, 0.875, 0.5, 0.125, 0]),
        ("Concave", [0.5, 1.0], [0.0, 0.5, 1.0, 2.0], [0.5 / 1.5, 0.5, 1, 1]),
        ("Constant", [0.333], [0, 7], [0.333, 0.333]),
        ("Triangle", [0, 5, 10, 0.5], [5], [0.5]),  # optional height
    ],
)
def test_hand_computed_values(kind: str, params: list[float], x: list[float], expected: list[float]) -> None:
    term = build_term(kind, "t", [float(p) for p in params])
    np.testing.assert_allclose(term.membership(np.array(x, dtype=float)), expected, atol=1e-12)


@pytest.mark.parametrize(
    ("kind", "params", "reference"),
    [
        ("Triangle", [1.0, 4.0, 9.0], lambda x: fuzz.trimf(x, [1.0, 4.0, 9.0])),
        ("Trapezoid", [1.0, 3.0, 6.0, 9.0], lambda x: fuzz.trapmf(x, [1.0, 3.0, 6.0, 9.0])),
        ("Gaussian", [5.0, 1.5], lambda x: fuzz.gaussmf(x, 5.0, 1.5)),
        ("Bell", [5.0, 2.0, 3.0], lambda x: fuzz.gbellmf(x, 2.0, 3.0, 5.0)),
        ("Sigmoid", [5.0, 2.0], lambda x: fuzz.sigmf(x, 5.0, 2.0)),
        ("SShape", [2.0, 8.0], lambda x: fuzz.smf(x, 2.0, 8.0)),
        ("ZShape", [2.0, 8.0], lambda x: fuzz.zmf(x, 2.0, 8.0)),
    ],
)
def test_same_function_as_scikit_fuzzy(kind: str, params: list[float], reference: object) -> None:
    term = build_term(kind, "t", params)
    np.testing.assert_allclose(term.membership(X), reference(X), atol=1e-12)  # type: ignore[operator]


def test_any_shape_and_nan() -> None:
    term = build_term("Triangle", "t", [0.0, 1.0, 2.0])
    grid = np.array([[0.5, np.nan], [1.5, 3.0]])
    out = term.membership(grid)
    assert out.shape == (2, 2)
    assert np.isnan(out[0, 1])
    np.testing.assert_allclose(out[[0, 1, 1], [0, 0, 1]], [0.5, 0.5, 0.0])


def test_infinite_vertices_are_shoulders() -> None:
    left = build_term("Trapezoid", "t", [-math.inf, -math.inf, 0.0, 1.0])
    np.testing.assert_allclose(left.membership(np.array([-1e9, 0.5, 2.0])), [1.0, 0.5, 0.0])


@pytest.mark.parametrize(
    ("kind", "params", "why"),
    [
        ("Triangle", [0.0, 5.0], "takes 3 or 4"),
        ("Triangle", [5.0, 0.0, 10.0], "a <= b <= c"),
        ("Ramp", [1.0, 1.0], "must differ"),
        ("Gaussian", [0.0, 0.0], "positive"),
        ("Triangel", [0.0, 1.0, 2.0], "did you mean 'Triangle'"),
        ("Constant", [1.0, 2.0], "takes 1"),
    ],
)
def test_bad_terms_are_refused(kind: str, params: list[float], why: str) -> None:
    with pytest.raises(ConfigError, match=why):
        build_term(kind, "t", params)


MONOTONIC = [(name, cls) for name, cls in TERMS.items() if cls.MONOTONIC]
SHAPES = {
    "Ramp": [[0.0, 0.25], [0.6, 0.4]],
    "Sigmoid": [[0.13, 30.0], [0.5, -30.0]],
    "SShape": [[0.0, 0.25]],
    "ZShape": [[0.3, 0.6]],
    "Concave": [[0.24, 0.25], [0.5, 0.4]],
}


def test_every_monotonic_term_has_a_shape_to_check() -> None:
    assert {name for name, _ in MONOTONIC} == set(SHAPES)


@pytest.mark.parametrize(("kind", "params"), [(k, p) for k, ps in SHAPES.items() for p in ps])
@given(y=st.floats(min_value=0.01, max_value=0.99))
def test_tsukamoto_inverts_membership(kind: str, params: list[float], y: float) -> None:
    term = build_term(kind, "t", params)
    x = term.tsukamoto(np.array([y]))
    assert term.membership(x)[0] == pytest.approx(y, abs=1e-9)


def test_non_monotonic_term_has_no_tsukamoto() -> None:
    with pytest.raises(ConfigError, match="not monotonic"):
        build_term("Triangle", "t", [0.0, 1.0, 2.0]).tsukamoto(0.5)
