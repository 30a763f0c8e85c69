"""Fuzzy engine speed: our vectorised engine against scikit-fuzzy's ControlSystemSimulation.

Same engine, same inputs, same discretised universe: the robot's IDLE engine (6 inputs, 14 rules,
2 outputs) as a Mamdani twin (Minimum implication, because scikit-fuzzy has no product implication)
with a 201-point output universe (`DiscreteCentroid`, scikit-fuzzy's centroid). Input terms are
piecewise linear with breakpoints on scikit-fuzzy's 121-point input universe, so both sides compute the
same numbers: the benchmark checks they agree within 1e-6 before reporting the speed ratio.

A second row times the shipped IDLE engine itself (Larsen, fuzzylite-style Centroid 200) on the same
rows against evaluating them one at a time with the same engine, which shows what vectorising buys.

The last rows time ONE row per call, what the 50 Hz control tick does: `Engine.process` (the plan
compiled at load time, `atemr.skills.fuzzy.compiled`) against the rule-by-rule evaluation it replaced
(`Engine.process_columns_generic`, called as `process` used to call it), for the shipped IDLE and MANUAL
engines, and the Mamdani twin against one scikit-fuzzy ``compute()`` per row. Results are checked equal.

The Takagi-Sugeno rows time 100,000 rows in one batch against pyfuzzylite 8 (numpy-vectorised, a
benchmark-only dependency) on the same `.fll` text: fuzzylite's own ObstacleAvoidance example (from
``../shared/reference/fuzzylite``; skipped when absent) and a 3-input, 27-rule grid of Constant and Linear
outputs. Both are timed by interleaved trials (median CPU time); the outputs are checked to agree within
1e-6 of the output range.

Run: ``.venv/bin/python benchmarks/bench_fuzzy.py [--quick]``
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from atemr.skills.fuzzy import Engine, load_builtin_engine
from atemr.skills.fuzzy.discrete_centroid import DiscreteCentroid
from atemr.skills.fuzzy.fll import engine_from_fll
from atemr.skills.fuzzy.skfuzzy_bridge import to_skfuzzy

SEED = 20240601
REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "fuzzylite"


def mamdani_twin(engine: Engine, points: int = 201) -> Engine:
    """``engine`` with Minimum implication and a ``points``-point DiscreteCentroid on every output."""
    return Engine(
        f"{engine.name}-mamdani",
        engine.inputs,
        tuple(dataclasses.replace(o, defuzzifier=DiscreteCentroid(points)) for o in engine.outputs),
        tuple(dataclasses.replace(b, implication="Minimum") for b in engine.rule_blocks),
        type="Mamdani",
    )


def inputs(engine: Engine, rows: int) -> dict[str, np.ndarray]:
    """Sector distances strictly inside (0.4 m, 1.0 m), where every rule fires a little: scikit-fuzzy
    raises on rows where nothing fires, and fuzzylite's 1e-6 firing threshold never matters there."""
    data = np.random.default_rng(SEED).uniform(0.41, 0.99, size=(rows, len(engine.input_names)))
    return {name: data[:, i] for i, name in enumerate(engine.input_names)}


def best_of(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Shortest wall time of ``repeat`` runs (the machine may be busy) and the last result."""
    times = []
    result = None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), result


def run(quick: bool = False) -> list[dict[str, Any]]:
    """Measure and return the benchmark rows (see the module docstring)."""
    from skfuzzy import control as ctrl

    rows = 1_000 if quick else 10_000
    twin = mamdani_twin(load_builtin_engine("idle"))
    x = inputs(twin, rows)

    def skfuzzy_run() -> dict[str, np.ndarray]:
        with warnings.catch_warnings():  # scikit-fuzzy 0.5 uses np.maximum(a, b, out), deprecated in numpy 2.4
            warnings.simplefilter("ignore", DeprecationWarning)
            sim = ctrl.ControlSystemSimulation(to_skfuzzy(twin), cache=False)
            sim.inputs(x)
            sim.compute()
        return {k: np.asarray(v) for k, v in sim.output.items()}

    ours_s, ours = best_of(lambda: twin.process(x), 3)
    base_s, base = best_of(skfuzzy_run, 1)
    worst = max(float(np.max(np.abs(ours[n] - base[n]))) for n in twin.output_names)
    if not worst <= 1e-6:
        raise AssertionError(f"outputs differ from scikit-fuzzy by {worst:.3g} (> 1e-6)")
    result = [{
        "what": f"IDLE Mamdani twin, {rows} rows vs skfuzzy ControlSystemSimulation (max diff {worst:.1e})",
        "ours": rows / ours_s, "baseline": rows / base_s, "ratio": base_s / ours_s, "goal": 100.0,
        "unit": "rows/s",
    }]

    idle = load_builtin_engine("idle")
    loop_rows = 200 if quick else 1_000
    batch_s, _ = best_of(lambda: idle.process(x), 3)
    one = {k: v[:loop_rows] for k, v in x.items()}
    loop_s, _ = best_of(lambda: [idle.process({k: v[i] for k, v in one.items()}) for i in range(loop_rows)], 1)
    result.append({
        "what": f"IDLE engine (Larsen, Centroid 200), {rows} rows batched vs one row per call",
        "ours": rows / batch_s, "baseline": loop_rows / loop_s, "ratio": (loop_s / loop_rows) / (batch_s / rows),
        "goal": None, "unit": "rows/s",
    })
    result += single_row(quick)
    result += takagi_sugeno(quick)
    return result


def grid_fll() -> str:
    """A Takagi-Sugeno engine as `.fll`: 3 inputs of 3 triangles, every combination a rule (27), 9 Constant
    and 9 Linear output terms, Minimum conjunction, WeightedAverage."""
    lines = ["Engine: grid27"]
    for name in ("a", "b", "c"):
        lines += [f"InputVariable: {name}", "  enabled: true", "  range: 0.000 1.000", "  lock-range: false",
                  "  term: low Triangle -0.500 0.000 0.500", "  term: mid Triangle 0.000 0.500 1.000",
                  "  term: high Triangle 0.500 1.000 1.500"]
    lines += ["OutputVariable: out", "  enabled: true", "  range: -2.000 2.000", "  lock-range: false",
              "  aggregation: Maximum", "  defuzzifier: WeightedAverage TakagiSugeno", "  default: nan",
              "  lock-previous: false"]
    lines += [f"  term: k{i} Constant {-1 + i / 4:.3f}" for i in range(9)]
    lines += [f"  term: l{i} Linear {0.1 * i:.3f} {-0.2:.3f} {0.05 * i:.3f} {0.1:.3f}" for i in range(9)]
    lines += ["RuleBlock: rules", "  enabled: true", "  conjunction: Minimum", "  disjunction: Maximum",
              "  implication: none", "  activation: General"]
    levels = ("low", "mid", "high")
    for i, (x, y, z) in enumerate((x, y, z) for x in levels for y in levels for z in levels):
        term = f"k{i % 9}" if i % 2 else f"l{i % 9}"
        lines.append(f"  rule: if a is {x} and b is {y} and c is {z} then out is {term}")
    return "\n".join(lines) + "\n"


def takagi_sugeno(quick: bool = False) -> list[dict[str, Any]]:
    """Rows for batched Takagi-Sugeno engines against pyfuzzylite (see the module docstring)."""
    try:
        import fuzzylite as fl
    except ImportError:
        return [{"what": "Takagi-Sugeno vs pyfuzzylite: skipped, pyfuzzylite is not installed (the bench extra)",
                 "ours": None, "baseline": None, "ratio": None, "goal": None, "unit": ""}]
    engines = {"grid27 (3 inputs, 27 rules, Constant and Linear)": grid_fll()}
    example = REFERENCE / "takagi-sugeno_ObstacleAvoidance.fll"
    if example.is_file():
        engines = {"fuzzylite's ObstacleAvoidance (1 input, 2 rules)": example.read_text(), **engines}
    rows = 20_000 if quick else 100_000
    trials = 5 if quick else 25
    result: list[dict[str, Any]] = []
    if not example.is_file():
        result.append({"what": f"Takagi-Sugeno ObstacleAvoidance: skipped, {example} is absent", "ours": None,
                       "baseline": None, "ratio": None, "goal": None, "unit": ""})
    for label, text in engines.items():
        ours = engine_from_fll("bench.fll", text)
        theirs = fl.FllImporter().from_string(text)
        data = np.random.default_rng(SEED).uniform(0.0, 1.0, size=(len(ours.input_names), rows))

        def run_ours(e: Engine = ours, d: np.ndarray = data) -> np.ndarray:
            return e.process({name: d[i] for i, name in enumerate(e.input_names)})[e.output_names[0]]

        def run_theirs(e: Any = theirs, d: np.ndarray = data) -> np.ndarray:
            for i, variable in enumerate(e.input_variables):
                variable.value = d[i]
            e.process()
            return np.asarray(e.output_variables[0].value)

        # within 1e-6 of the output range, as tests/skills/fuzzy/test_against_pyfuzzylite.py (which says why)
        worst = float(np.nanmax(np.abs(run_ours() - run_theirs())))
        span = ours.outputs[0].maximum - ours.outputs[0].minimum
        if not worst <= 1e-6 * span:
            raise AssertionError(f"{label}: outputs differ from pyfuzzylite by {worst:.3g} (> 1e-6 of the range)")
        ours_s, theirs_s = interleaved(run_ours, run_theirs, trials)
        result.append({
            "what": f"Takagi-Sugeno {label}, {rows:,} rows in one batch vs pyfuzzylite (max diff {worst:.1e})",
            "ours": rows / ours_s, "baseline": rows / theirs_s, "ratio": theirs_s / ours_s, "goal": 1.0,
            "unit": "rows/s",
        })
    return result


def interleaved(ours: Callable[[], Any], theirs: Callable[[], Any], trials: int) -> tuple[float, float]:
    """Median CPU seconds of each over ``trials`` alternating runs: a busy machine slows both alike."""
    times: tuple[list[float], list[float]] = ([], [])
    for _ in range(trials):
        for fn, out in ((ours, times[0]), (theirs, times[1])):
            start = time.thread_time()
            fn()
            out.append(time.thread_time() - start)
    return statistics.median(times[0]), statistics.median(times[1])


def generic_call(engine: Engine, row: dict[str, float]) -> dict[str, np.ndarray]:
    """One row through the rule-by-rule path, as `Engine.process` did before it ran the compiled plan."""
    columns = {k: np.asarray(v, dtype=np.float64).reshape(-1) for k, v in row.items()}
    return {k: v.reshape(()) for k, v in engine.process_columns_generic(columns).items()}


def single_row(quick: bool = False) -> list[dict[str, Any]]:
    """Rows for one input row per call (the control tick's case); see the module docstring."""
    from skfuzzy import control as ctrl

    calls = 300 if quick else 2_000
    rows: list[dict[str, Any]] = []
    for name in ("idle", "manual"):
        engine = load_builtin_engine(name)
        data = inputs(engine, calls)
        scenes = [{k: float(v[i]) for k, v in data.items()} for i in range(calls)]
        ours_s, ours = best_of(lambda e=engine, sc=scenes: [e.process(r) for r in sc], 5)
        base_s, base = best_of(lambda e=engine, sc=scenes: [generic_call(e, r) for r in sc], 2)
        worst = max(abs(float(a[k]) - float(b[k])) for a, b in zip(ours, base, strict=True) for k in a)
        if not worst <= 1e-12:
            raise AssertionError(f"{engine.name}: compiled and rule-by-rule paths differ by {worst:.3g}")
        rows.append({
            "what": f"{engine.name} engine, one row per call: compiled plan vs rule-by-rule path "
                    f"({1e6 * ours_s / calls:.0f} µs vs {1e6 * base_s / calls:.0f} µs per call)",
            "ours": calls / ours_s, "baseline": calls / base_s, "ratio": base_s / ours_s, "goal": None,
            "unit": "calls/s",
        })

    twin = mamdani_twin(load_builtin_engine("idle"))
    sk_calls = 50 if quick else 200
    data = inputs(twin, sk_calls)
    scenes = [{k: float(v[i]) for k, v in data.items()} for i in range(sk_calls)]
    with warnings.catch_warnings():  # see run(): scikit-fuzzy 0.5 on numpy 2.4
        warnings.simplefilter("ignore", DeprecationWarning)
        sim = ctrl.ControlSystemSimulation(to_skfuzzy(twin))

        def skfuzzy_rows() -> list[dict[str, float]]:
            out = []
            for r in scenes:
                sim.inputs(r)
                sim.compute()
                out.append(dict(sim.output))
            return out

        base_s, base = best_of(skfuzzy_rows, 1)
    ours_s, ours = best_of(lambda: [twin.process(r) for r in scenes], 5)
    worst = max(abs(float(a[k]) - float(b[k])) for a, b in zip(ours, base, strict=True) for k in a)
    if not worst <= 1e-6:
        raise AssertionError(f"single rows differ from scikit-fuzzy by {worst:.3g} (> 1e-6)")
    rows.append({
        "what": f"IDLE Mamdani twin, one row per call vs skfuzzy compute() per row "
                f"({1e6 * ours_s / sk_calls:.0f} µs vs {1e6 * base_s / sk_calls:.0f} µs per call)",
        "ours": sk_calls / ours_s, "baseline": sk_calls / base_s, "ratio": base_s / ours_s, "goal": None,
        "unit": "calls/s",
    })
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1,000 rows instead of 10,000")
    args = parser.parse_args()
    for row in run(quick=args.quick):
        goal = f" (goal ≥{row['goal']:g}×)" if row["goal"] else ""
        print(f"{row['what']}\n  ours {row['ours']:,.0f} {row['unit']}, baseline {row['baseline']:,.0f} "
              f"{row['unit']}: {row['ratio']:,.1f}×{goal}")


if __name__ == "__main__":
    main()
