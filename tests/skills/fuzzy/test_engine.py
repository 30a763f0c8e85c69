"""Engine evaluation on small engines whose results are computed by hand in the comments."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atemr.skills.fuzzy import FuzzyInputError
from atemr.skills.fuzzy.engine import Engine
from atemr.skills.fuzzy.yaml_format import engine_from_yaml


def engine(outputs: str, rules: str, implication: str = "Minimum", extra_block: str = "") -> Engine:
    text = f"""
name: T
inputs:
  x:
    range: [0.0, 1.0]
    terms: {{LOW: Ramp 1 0, HIGH: Ramp 0 1}}
outputs:
{outputs}
rule_blocks:
  - conjunction: Minimum
    disjunction: Maximum
    implication: {implication}
    rules:
{rules}
{extra_block}"""
    return engine_from_yaml("t.yaml", text=text)


TRIANGLES = """  y:
    range: [0.0, 1.0]
    defuzzifier: Centroid 4
    aggregation: Maximum
    terms: {A: Triangle 0 0 1, B: Triangle 0 1 1}"""
RULES_AB = """      - if x is LOW then y is A
      - if x is HIGH then y is B"""


def test_mamdani_minimum_by_hand() -> None:
    # Samples 0.125 .. 0.875; x = 0.25: LOW 0.75, HIGH 0.25.
    # A clipped at 0.75: .75 .625 .375 .125; B clipped at .25: .125 .25 .25 .25; max: .75 .625 .375 .25
    # centroid = (.75·.125 + .625·.375 + .375·.625 + .25·.875) / 2.0 = .78125 / 2 = 0.390625
    out = engine(TRIANGLES, RULES_AB).process({"x": 0.25})
    assert float(out["y"]) == pytest.approx(0.390625, abs=1e-12)


def test_larsen_by_hand() -> None:
    # A scaled by .75: .65625 .46875 .28125 .09375; B by .25: .03125 .09375 .15625 .21875
    # max: .65625 .46875 .28125 .21875 → sum 1.625, moment .625 → 0.384615...
    out = engine(TRIANGLES, RULES_AB, implication="AlgebraicProduct").process({"x": 0.25})
    assert float(out["y"]) == pytest.approx(0.625 / 1.625, abs=1e-12)


def test_no_rule_fired_gives_the_default() -> None:
    outputs = TRIANGLES + "\n    default: -1.0"
    eng = engine(outputs, "      - if x is HIGH then y is B")
    out = eng.process({"x": [0.0, 0.0000005, 0.5]})
    # 0 and 5e-7 are below fuzzylite's firing threshold (1e-6): default; 0.5 fires → centroid of B clipped
    assert out["y"][0] == -1.0 and out["y"][1] == -1.0
    assert out["y"][2] == pytest.approx((0.125 * 0.125 + 0.375 * 0.375 + 0.5 * 0.625 + 0.5 * 0.875) / 1.5)


def test_default_nan_when_unset() -> None:
    out = engine(TRIANGLES, "      - if x is HIGH then y is B").process({"x": 0.0})
    assert math.isnan(float(out["y"]))


def test_rule_weight_and_hedges() -> None:
    outputs = """  y:
    range: [0.0, 1.0]
    defuzzifier: WeightedSum TakagiSugeno
    terms: {ONE: Constant 1.0}"""
    eng = engine(outputs, "      - if x is very HIGH then y is ONE with 0.5", implication="none")
    # x = 0.6: HIGH 0.6, very → 0.36, weight 0.5 → 0.18; weighted sum with z = 1 → 0.18
    assert float(eng.process({"x": 0.6})["y"]) == pytest.approx(0.18)
    eng = engine(outputs, "      - if x is not HIGH then y is ONE", implication="none")
    assert float(eng.process({"x": 0.25})["y"]) == pytest.approx(0.75)


def test_takagi_sugeno_linear_and_constant() -> None:
    outputs = """  y:
    range: [-10.0, 10.0]
    defuzzifier: WeightedAverage
    terms: {LIN: Linear 2.0 1.0, K: Constant -1.0}"""
    rules = """      - if x is HIGH then y is LIN
      - if x is LOW then y is K"""
    # x = 0.25: w(LIN) = .25 with z = 2·.25 + 1 = 1.5; w(K) = .75 with z = -1 → (.375 - .75)/1 = -0.375
    out = engine(outputs, rules, implication="none").process({"x": [0.25, 1.0]})
    np.testing.assert_allclose(out["y"], [-0.375, 3.0])


def test_tsukamoto_by_hand() -> None:
    outputs = """  y:
    range: [0.0, 1.0]
    defuzzifier: WeightedAverage Tsukamoto
    terms: {UP: Ramp 0 1, DOWN: Ramp 1 0.5}"""
    rules = """      - if x is HIGH then y is UP
      - if x is LOW then y is DOWN"""
    # x = 0.25: UP w=.25 → z=.25; DOWN w=.75 → z = 1 - .5·.75 = .625 → (.0625 + .46875)/1 = 0.53125
    out = engine(outputs, rules, implication="none").process({"x": 0.25})
    assert float(out["y"]) == pytest.approx(0.53125)


def test_same_term_degrees_are_grouped_by_the_aggregation() -> None:
    outputs = """  y:
    range: [0.0, 1.0]
    aggregation: AGG
    defuzzifier: WeightedSum TakagiSugeno
    terms: {ONE: Constant 1.0}"""
    rules = """      - if x is HIGH then y is ONE
      - if x is LOW then y is ONE"""
    # x = 0.25: degrees .25 and .75 on the same term: Maximum → .75, none (sum) → 1.0
    for agg, expected in (("Maximum", 0.75), ("none", 1.0)):
        eng = engine(outputs.replace("AGG", agg), rules, implication="none")
        assert float(eng.process({"x": 0.25})["y"]) == pytest.approx(expected)


@pytest.mark.parametrize("kind", ["Bisector", "MeanOfMaximum", "SmallestOfMaximum", "LargestOfMaximum"])
def test_other_integral_defuzzifiers_by_hand(kind: str) -> None:
    outputs = f"""  y:
    range: [0.0, 1.0]
    aggregation: Maximum
    defuzzifier: {kind} 4
    terms: {{A: Rectangle 0 0.5, B: Rectangle 0.5 1}}"""
    # x = 0.25: samples .125 .375 (A at .75) and .625 .875 (B at .25): y = .75 .75 .25 .25
    # bisector (fuzzylite's): cumulative shares .375 .75 .875 1; the first sample's is closest to one half
    expected = {"Bisector": 0.125, "MeanOfMaximum": 0.25, "SmallestOfMaximum": 0.125,
                "LargestOfMaximum": 0.375}
    out = engine(outputs, RULES_AB).process({"x": 0.25})
    assert float(out["y"]) == pytest.approx(expected[kind])


def test_shapes_scalars_and_broadcasting() -> None:
    eng = engine(TRIANGLES, RULES_AB)
    assert eng.process({"x": 0.3})["y"].shape == ()
    assert eng.process({"x": [0.3]})["y"].shape == (1,)
    grid = np.linspace(0, 1, 12).reshape(3, 4)
    out = eng.process({"x": grid})["y"]
    assert out.shape == (3, 4)
    assert out[1, 2] == pytest.approx(float(eng.process({"x": grid[1, 2]})["y"]))


def test_rows_are_independent_of_batch() -> None:
    eng = engine(TRIANGLES, RULES_AB, implication="AlgebraicProduct")
    xs = np.random.default_rng(3).uniform(0, 1, 257)
    batch = eng.process({"x": xs})["y"]
    single = np.array([float(eng.process({"x": v})["y"]) for v in xs[:20]])
    np.testing.assert_allclose(batch[:20], single, rtol=0, atol=1e-15)


def test_lock_range_clips_inputs() -> None:
    text = """
inputs:
  x: {range: [0.0, 1.0], lock_range: true, terms: {LOW: Ramp 1 0, HIGH: Ramp 0 1}}
outputs:
  y: {range: [0.0, 1.0], defuzzifier: WeightedAverage TakagiSugeno, terms: {ONE: Constant 1, ZERO: Constant 0}}
rule_blocks:
  - rules: [if x is HIGH then y is ONE, if x is LOW then y is ZERO]
"""
    eng = engine_from_yaml("t.yaml", text=text)
    np.testing.assert_allclose(eng.process({"x": [-5.0, 5.0]})["y"], [0.0, 1.0])


def test_bad_inputs_raise_the_projects_error() -> None:
    eng = engine(TRIANGLES, RULES_AB)
    with pytest.raises(FuzzyInputError, match="missing input"):
        eng.process({})
    with pytest.raises(FuzzyInputError, match=r"unknown input.*z"):
        eng.process({"x": 0.1, "z": 1.0})
    with pytest.raises(FuzzyInputError, match="not numeric"):
        eng.process({"x": "near"})


def test_names_and_describe() -> None:
    eng = engine(TRIANGLES, RULES_AB)
    assert eng.input_names == ("x",) and eng.output_names == ("y",)
    text = eng.describe()
    assert "InputVariable: x" in text and "defuzzifier: Centroid 4" in text and "rule: if x is LOW then y is A" in text
