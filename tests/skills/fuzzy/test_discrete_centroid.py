"""DiscreteCentroid and the separable fast path agree with scikit-fuzzy and with the general path."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.skills.fuzzy import Engine, load_builtin_engine
from atemr.skills.fuzzy.discrete_centroid import DiscreteCentroid
from atemr.skills.fuzzy.skfuzzy_bridge import to_skfuzzy
from atemr.skills.fuzzy.yaml_format import engine_from_yaml

ctrl = pytest.importorskip("skfuzzy.control", reason="scikit-fuzzy's control module needs networkx")
# scikit-fuzzy 0.5 calls np.maximum(a, b, out) positionally, which numpy 2.4 deprecates: not our code
SKFUZZY_WARNING = pytest.mark.filterwarnings("ignore:Passing more than 2 positional arguments:DeprecationWarning")

OVERLAPPING = """
name: overlap
inputs:
  a: {range: [0.0, 1.0], terms: {LOW: Ramp 0.9 0.1, HIGH: Ramp 0.1 0.9}}
  b: {range: [0.0, 1.0], terms: {LOW: Ramp 0.9 0.1, HIGH: Ramp 0.1 0.9}}
outputs:
  y:
    range: [0.0, 1.0]
    aggregation: Maximum
    defuzzifier: DiscreteCentroid 101
    terms: {LOW: Triangle 0 0.25 0.6, MID: Triangle 0.2 0.5 0.8, HIGH: Trapezoid 0.4 0.75 1.0 1.0}
rule_blocks:
  - conjunction: Minimum
    disjunction: Maximum
    implication: Minimum
    rules:
      - if a is LOW and b is LOW then y is LOW
      - if a is HIGH or b is not LOW then y is MID
      - if a is HIGH and b is HIGH then y is HIGH
      - if a is LOW and b is HIGH then y is LOW
"""


def skfuzzy_outputs(engine: Engine, columns: dict[str, np.ndarray], input_points: int) -> dict[str, np.ndarray]:
    sim = ctrl.ControlSystemSimulation(to_skfuzzy(engine, input_points=input_points), cache=False)
    sim.inputs(columns)
    sim.compute()
    return {k: np.asarray(v) for k, v in sim.output.items()}


def random_columns(engine: Engine, rows: int, low: float, high: float, seed: int) -> dict[str, np.ndarray]:
    data = np.random.default_rng(seed).uniform(low, high, size=(rows, len(engine.inputs)))
    return {n: data[:, i] for i, n in enumerate(engine.input_names)}


@SKFUZZY_WARNING
def test_overlapping_terms_match_scikit_fuzzy() -> None:
    engine = engine_from_yaml("overlap.yaml", text=OVERLAPPING)
    x = random_columns(engine, 200, 0.15, 0.85, seed=1)
    ours = engine.process(x)["y"]
    reference = skfuzzy_outputs(engine, x, input_points=101)["y"]
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-9)


def idle_twin() -> Engine:
    idle = load_builtin_engine("idle")
    return Engine("twin", idle.inputs,
                  tuple(dataclasses.replace(o, defuzzifier=DiscreteCentroid(201)) for o in idle.outputs),
                  tuple(dataclasses.replace(b, implication="Minimum") for b in idle.rule_blocks))


@SKFUZZY_WARNING
def test_robot_engine_twin_matches_scikit_fuzzy_on_both_paths(monkeypatch: pytest.MonkeyPatch) -> None:
    twin = idle_twin()
    x = random_columns(twin, 200, 0.41, 0.99, seed=2)
    reference = skfuzzy_outputs(twin, x, input_points=121)
    fast = twin.process(x)
    monkeypatch.setattr("atemr.skills.fuzzy.discrete_centroid.is_separable", lambda m, names: False)
    general = twin.process(x)
    for name in twin.output_names:
        np.testing.assert_allclose(fast[name], reference[name], rtol=0, atol=1e-9)
        np.testing.assert_allclose(general[name], reference[name], rtol=0, atol=1e-9)


def test_bridge_refuses_what_scikit_fuzzy_cannot_do() -> None:
    with pytest.raises(ConfigError, match="DiscreteCentroid"):
        to_skfuzzy(load_builtin_engine("idle"))
    larsen = dataclasses.replace(idle_twin().rule_blocks[0], implication="AlgebraicProduct")
    twin = idle_twin()
    with pytest.raises(ConfigError, match="Minimum/Maximum/Minimum"):
        to_skfuzzy(Engine("x", twin.inputs, twin.outputs, (larsen,)))
