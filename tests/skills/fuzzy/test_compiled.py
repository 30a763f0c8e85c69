"""The compiled evaluation plan gives the rule-by-rule path's results, for every kind of engine we have.

`Engine.process` runs the plan compiled at load time; `Engine.process_columns_generic` is the previous,
rule-by-rule evaluation. Both must agree on random rows (inside and outside the ranges, on term vertices,
NaN) for the shipped engines, fuzzylite's reference engines and small engines that use every feature the
plan treats specially (hedges, weights, other norms, aggregations, defuzzifiers and term shapes).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from atemr.skills.fuzzy import Engine, load_builtin_engine, load_engine
from atemr.skills.fuzzy.discrete_centroid import DiscreteCentroid
from atemr.skills.fuzzy.terms import Ramp, Trapezoid, Triangle
from atemr.skills.fuzzy.yaml_format import engine_from_yaml

REFERENCE = [
    "hybrid_ObstacleAvoidance",
    "mamdani_ObstacleAvoidance",
    "mamdani_SimpleDimmer",
    "mamdani_matlab_tipper",
    "takagi-sugeno_ObstacleAvoidance",
    "tsukamoto_tsukamoto",
]

#: Larger than rounding differences of reordered sums (a few 1e-16), far below any real difference.
ATOL = 1e-12


def rows(engine: Engine, n: int, seed: int) -> dict[str, np.ndarray]:
    """Random values over each input's range and a little beyond, with its term vertices and NaN mixed in."""
    rng = np.random.default_rng(seed)
    columns = {}
    for var in engine.inputs:
        span = var.maximum - var.minimum
        x = rng.uniform(var.minimum - 0.2 * span, var.maximum + 0.2 * span, n)
        vertices = np.array([p for t in var.terms for p in t.params if math.isfinite(p)] or [var.minimum])
        pick = rng.random(n)
        x = np.where(pick < 0.15, rng.choice(vertices, n), x)
        x[pick > 0.98] = np.nan
        columns[var.name] = x
    return columns


def assert_same(engine: Engine, columns: dict[str, np.ndarray]) -> None:
    compiled = engine.process_columns(columns)
    generic = engine.process_columns_generic(columns)
    assert list(compiled) == list(generic) == list(engine.output_names)
    for name in engine.output_names:
        got, expected = compiled[name], generic[name]
        assert got.shape == expected.shape
        np.testing.assert_array_equal(np.isnan(got), np.isnan(expected), err_msg=f"{engine.name} {name}: NaN rows")
        inf = np.isinf(expected)
        np.testing.assert_array_equal(got[inf], expected[inf], err_msg=f"{engine.name} {name}: inf rows")
        finite = np.isfinite(expected)
        np.testing.assert_allclose(got[finite], expected[finite], rtol=0, atol=ATOL, err_msg=f"{engine.name} {name}")


def mamdani_twin(engine: Engine) -> Engine:
    return Engine(f"{engine.name}-mamdani", engine.inputs,
                  tuple(dataclasses.replace(o, defuzzifier=DiscreteCentroid(201)) for o in engine.outputs),
                  tuple(dataclasses.replace(b, implication="Minimum") for b in engine.rule_blocks), type="Mamdani")


@pytest.mark.parametrize("name", ["idle", "manual"])
def test_shipped_engines(name: str) -> None:
    engine = load_builtin_engine(name)
    for seed in range(3):
        assert_same(engine, rows(engine, 3000, seed))


def test_shipped_engines_on_every_crisp_situation() -> None:
    grid = np.array(np.meshgrid(*[[0.0, 0.3, 0.4, 0.7, 1.0, 1.2]] * 6)).reshape(6, -1)
    for engine in (load_builtin_engine("idle"), load_builtin_engine("manual")):
        assert_same(engine, {name: grid[i] for i, name in enumerate(engine.input_names)})


def test_mamdani_twin_of_idle() -> None:
    twin = mamdani_twin(load_builtin_engine("idle"))
    assert_same(twin, rows(twin, 500, 4))


@pytest.mark.parametrize("example", REFERENCE)
def test_fuzzylite_reference_engines(shared_dir: Path, example: str) -> None:
    path = shared_dir / "reference" / "fuzzylite" / f"{example}.fll"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    engine = load_engine(path)
    assert_same(engine, rows(engine, 2000, 5))


FEATURES = """
name: features
inputs:
  a: {range: [0.0, 1.0], lock_range: true,
      terms: {LOW: Ramp 0.9 0.1, HIGH: Ramp 0.1 0.9 0.8, MID: Triangle 0.2 0.5 0.8}}
  b: {range: [-1.0, 1.0],
      terms: {NEG: Trapezoid -inf -1 -0.5 0.1, POS: Trapezoid -0.1 0.5 1 inf, ZERO: Gaussian 0 0.3,
              SHARP: Triangle -inf 0 0.5 0.9, BELL: Bell 0.5 0.2 2}}
  c: {range: [0.0, 10.0], terms: {S: Sigmoid 5 2, Z: ZShape 2 6, SS: SShape 4 8, REC: Rectangle 3 7,
                                  CONC: Concave 4 8}}
outputs:
  integral:
    range: [0.0, 1.0]
    aggregation: Maximum
    defuzzifier: Centroid 50
    lock_range: true
    default: -1
    terms: {A: Triangle 0 0.2 0.4, B: Triangle 0.3 0.5 0.7, C: Ramp 0.6 1.0}
  larsen:
    range: [0.0, 1.0]
    defuzzifier: Centroid 50
    terms: {A: Triangle 0 0.2 0.4, B: Triangle 0.5 0.7 0.9, C: Ramp 0.9 1.0}
  larsen2:
    range: [-1.0, 1.0]
    defuzzifier: Centroid 30
    default: 0
    lock_range: true
    terms: {L: Triangle -1 -0.5 0, R: Triangle 0 0.5 1}
  separable_min:
    range: [0.0, 1.0]
    aggregation: Maximum
    defuzzifier: Centroid 40
    terms: {A: Triangle 0 0.2 0.4, B: Triangle 0.5 0.7 0.9}
  probsum:
    range: [0.0, 1.0]
    aggregation: AlgebraicSum
    defuzzifier: Bisector 64
    terms: {A: Triangle 0 0.2 0.4, B: Triangle 0.3 0.5 0.7}
  mom:
    range: [0.0, 1.0]
    defuzzifier: MeanOfMaximum 64
    terms: {A: Trapezoid 0 0.1 0.3 0.5, B: Triangle 0.3 0.5 0.7}
  ts_sum:
    range: [-10.0, 10.0]
    aggregation: none
    defuzzifier: WeightedSum TakagiSugeno
    terms: {ONE: Constant 1.0, LIN: Linear 1 -2 0.5 3, K: Constant -2}
  ts_fold:
    range: [-10.0, 10.0]
    aggregation: AlgebraicSum
    defuzzifier: WeightedAverage TakagiSugeno
    lock_range: true
    terms: {ONE: Constant 1.0, K: Constant -2}
  tsukamoto:
    range: [0.0, 1.0]
    aggregation: Maximum
    defuzzifier: WeightedAverage Tsukamoto
    terms: {UP: Ramp 0 1 0.9, DOWN: Ramp 1 0.25, SIG: Sigmoid 0.5 10, SS: SShape 0.2 0.8, ZS: ZShape 0.1 0.6,
            CC: Concave 0.3 0.6 0.8}
  unused:
    range: [0.0, 1.0]
    defuzzifier: Centroid 10
    default: 0.25
    terms: {A: Triangle 0 0.5 1}
rule_blocks:
  - name: lattice
    conjunction: Minimum
    disjunction: Maximum
    implication: AlgebraicProduct
    rules:
      - if a is LOW and (b is NEG or b is very ZERO) then integral is A and ts_sum is ONE and larsen is A
      - if (a is HIGH or c is S) and (b is POS or c is not Z) then integral is B and ts_sum is LIN and larsen is B
          with 0.7
      - if a is somewhat MID or b is SHARP or c is seldom REC then integral is C and ts_sum is ONE
      - if a is LOW then integral is A and tsukamoto is UP and larsen is C and larsen2 is L
      - if b is BELL and c is extremely CONC then tsukamoto is DOWN and ts_fold is ONE
      - if c is SS then tsukamoto is SIG and ts_fold is K and ts_fold is ONE
      - if c is Z or a is HIGH then tsukamoto is SS and ts_sum is K and larsen2 is R and larsen is somewhat A
      - if b is NEG then tsukamoto is ZS with 0.5
      - if a is MID then tsukamoto is CC and ts_sum is very K
  - name: minimum
    conjunction: Minimum
    disjunction: Maximum
    implication: Minimum
    rules:
      - if a is LOW then separable_min is A and probsum is A and mom is A
      - if a is HIGH then separable_min is B and probsum is B and mom is B
      - if b is POS and a is MID then probsum is A and mom is A and integral is A
  - name: products
    conjunction: AlgebraicProduct
    disjunction: AlgebraicSum
    implication: Minimum
    rules:
      - if a is LOW and b is POS then probsum is B and integral is not C
      - if (a is HIGH or b is NEG) and c is S then mom is B and ts_fold is K with 0.6
      - if c is REC then ts_sum is somewhat ONE and tsukamoto is UP
"""


def test_every_feature_the_plan_treats_specially() -> None:
    engine = engine_from_yaml("features.yaml", text=FEATURES)
    plan = engine._plan
    assert plan.antecedents.tree_rules and plan.fuzzification.hedged and plan.grouping.hedges
    assert plan.grouping.folds and plan.defuzzification.others
    assert plan.defuzzification.n_lin == 2 and plan.defuzzification.n_empty == 1
    assert plan.antecedents.weights is not None
    for seed in range(4):
        assert_same(engine, rows(engine, 1500, seed))


def test_mixed_weighted_defuzzifiers_and_no_rules_at_all() -> None:
    text = """
inputs:
  x: {range: [0.0, 1.0], terms: {LOW: Ramp 1 0, HIGH: Ramp 0 1}}
outputs:
  avg: {range: [0.0, 1.0], defuzzifier: WeightedAverage, default: 0.5, terms: {A: Constant 0.2, B: Constant 0.9}}
  sum: {range: [0.0, 1.0], defuzzifier: WeightedSum, terms: {A: Constant 0.2, B: Constant 0.9}}
rule_blocks:
  - rules: [if x is LOW then avg is A and sum is B, if x is HIGH then avg is B and sum is A]
"""
    engine = engine_from_yaml("mixed.yaml", text=text)
    assert_same(engine, rows(engine, 500, 1))
    empty = Engine("empty", engine.inputs, engine.outputs, ())
    out = empty.process({"x": [0.1, 0.9]})
    np.testing.assert_array_equal(out["avg"], [0.5, 0.5])
    assert np.isnan(out["sum"]).all()
    assert_same(empty, rows(empty, 10, 2))


def test_membership_kernels_are_bit_identical_to_the_terms() -> None:
    rng = np.random.default_rng(11)
    engine = engine_from_yaml("features.yaml", text=FEATURES)
    shapes = {s.kind: s for s in engine._plan.fuzzification.shapes}
    assert {"Ramp", "Triangle", "Trapezoid", "other"} <= set(shapes)
    for kind, shape in shapes.items():
        x = rng.uniform(-12.0, 12.0, (400, len(engine.inputs)))
        for term, v in zip(shape.terms, shape.variables, strict=True):
            x[:40, v] = np.repeat([p for p in term.params if math.isfinite(p)], 40)[:40]
        x[-3:] = [np.nan, np.inf, -np.inf]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            got = shape.evaluate(x.T)
        for j, (term, v) in enumerate(zip(shape.terms, shape.variables, strict=True)):
            np.testing.assert_array_equal(got[j], term.membership(x[:, v]), err_msg=f"{kind} {term}")


@pytest.mark.parametrize("cls", [Ramp, Triangle, Trapezoid])
def test_stacked_shapes_match_random_terms(cls: type) -> None:
    rng = np.random.default_rng(12)
    terms = []
    for k in range(60):
        p = np.sort(rng.uniform(-1, 1, len(cls.PARAMS)))
        if cls is Ramp and k % 2:
            p = p[::-1]
        if cls is not Ramp and k % 5 == 0:
            p[0] = -np.inf
        if cls is not Ramp and k % 7 == 0:
            p[-1] = np.inf
        if k % 3 == 0 and cls is not Ramp:
            p[1] = p[0] if np.isfinite(p[0]) else p[1]
        terms.append(cls(f"T{k}", tuple(float(v) for v in p), float(rng.choice([1.0, 0.5, 2.0]))))
    from atemr.skills.fuzzy.compiled import _shape

    shape = _shape(cls.__name__, [(0, t) for t in terms])
    x = np.concatenate([rng.uniform(-1.5, 1.5, 500), [p for t in terms for p in t.params], [np.nan, np.inf, -np.inf]])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        got = shape.evaluate(x[None, :])
    for j, term in enumerate(terms):
        np.testing.assert_array_equal(got[j], term.membership(x), err_msg=str(term))


def test_separable_larsen_centroid_equals_the_sampled_one(monkeypatch: pytest.MonkeyPatch) -> None:
    idle = load_builtin_engine("idle")
    assert idle._plan.defuzzification.n_lin == 2  # both outputs take the matrix-product path
    monkeypatch.setattr("atemr.skills.fuzzy.compiled.is_separable", lambda m, names: False)
    sampled = load_builtin_engine("idle")  # compiled while no output looks separable
    assert sampled._plan.defuzzification.n_lin == 0
    x = rows(idle, 2000, 6)
    fast, slow = idle.process(x), sampled.process(x)
    for name in idle.output_names:
        np.testing.assert_allclose(fast[name], slow[name], rtol=0, atol=ATOL)


def test_chunked_rows_equal_one_chunk() -> None:
    for engine in (load_builtin_engine("idle"), engine_from_yaml("features.yaml", text=FEATURES)):
        x = rows(engine, 1000, 7)
        whole = engine.process(x)
        object.__setattr__(engine, "_plan", dataclasses.replace(engine._plan, chunk_rows=97))
        chunked = engine.process(x)
        for name in engine.output_names:  # BLAS products inside some defuzzifiers may round by batch size
            np.testing.assert_allclose(chunked[name], whole[name], rtol=0, atol=ATOL)


def test_scalar_fast_path_equals_arrays() -> None:
    manual = load_builtin_engine("manual")
    scene = {"FR": 0.5, "FL": 1, "LC": True, "RL": np.float64(0.45), "RR": 0.9, "RC": 1.2}
    one = manual.process(scene)
    arrays = manual.process({k: np.array([float(v)]) for k, v in scene.items()})
    for name in manual.output_names:
        assert one[name].shape == () and isinstance(one[name], np.ndarray)
        assert float(one[name]) == float(arrays[name][0])


def test_ramp_membership_is_its_select_form() -> None:
    # Ramp.membership clips one quotient instead of selecting among three cases; the numbers are the same
    rng = np.random.default_rng(13)
    for _ in range(200):
        s, e = rng.uniform(-2, 2, 2)
        term = Ramp("r", (float(s), float(e)), float(rng.choice([1.0, 0.7])))
        x = np.concatenate([rng.uniform(-3, 3, 300), [s, e, np.nextafter(s, e), np.nextafter(e, s)],
                            [np.nan, np.inf, -np.inf]])
        if s < e:
            expected = np.select([x <= s, x >= e], [0.0, 1.0], (x - s) / (e - s))
        else:
            expected = np.select([x >= s, x <= e], [0.0, 1.0], (s - x) / (s - e))
        expected = np.where(np.isnan(x), np.nan, term.height * expected)
        got = term.membership(x)
        np.testing.assert_array_equal(got, expected)
        assert not np.signbit(got[got == 0.0]).any()
        assert isinstance(term.membership(float(s)), np.ndarray) and term.membership(float(s)).shape == ()
