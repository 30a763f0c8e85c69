"""fuzzylite `.fll` import: every reference engine reproduces every row fuzzylite computed (to 1e-4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.skills.fuzzy import load_engine
from atemr.skills.fuzzy.fll import engine_from_fll

EXAMPLES = [
    "hybrid_ObstacleAvoidance",
    "mamdani_ObstacleAvoidance",
    "mamdani_SimpleDimmer",
    "mamdani_matlab_tipper",
    "takagi-sugeno_ObstacleAvoidance",
    "tsukamoto_tsukamoto",
]


def read_fld(path: Path) -> tuple[list[str], np.ndarray]:
    lines = [line for line in path.read_text().splitlines() if line.strip()]
    header = lines[0].split()
    return header, np.array([[float(v) for v in line.split()] for line in lines[1:]])


@pytest.mark.parametrize("example", EXAMPLES)
def test_matches_every_row_fuzzylite_computed(shared_dir: Path, example: str) -> None:
    folder = shared_dir / "reference" / "fuzzylite"
    if not (folder / f"{example}.fll").is_file():
        pytest.skip(f"{folder}/{example}.fll is absent")
    engine = load_engine(folder / f"{example}.fll")
    header, data = read_fld(folder / f"{example}.fld")
    assert header == [*engine.input_names, *engine.output_names]
    assert len(data) >= 1000
    out = engine.process({n: data[:, header.index(n)] for n in engine.input_names})
    for name in engine.output_names:
        expected = data[:, header.index(name)]
        got = out[name]
        # NaN (no rule fired) and ±inf (fuzzylite's Tsukamoto of a saturated Sigmoid) must match exactly
        np.testing.assert_array_equal(np.isnan(got), np.isnan(expected), err_msg=f"{example} {name}: NaN rows")
        inf = np.isinf(expected)
        np.testing.assert_array_equal(got[inf], expected[inf], err_msg=f"{example} {name}: inf rows")
        finite = np.isfinite(expected)
        np.testing.assert_allclose(got[finite], expected[finite], rtol=0, atol=1e-4, err_msg=f"{example} {name}")


def test_the_nan_and_inf_cases_are_really_exercised(shared_dir: Path) -> None:
    folder = shared_dir / "reference" / "fuzzylite"
    if not folder.is_dir():
        pytest.skip(f"{folder} is absent")
    _, dimmer = read_fld(folder / "mamdani_SimpleDimmer.fld")
    _, tsukamoto = read_fld(folder / "tsukamoto_tsukamoto.fld")
    assert np.isnan(dimmer).any() and np.isinf(tsukamoto).any()


FLL = """Engine: e
InputVariable: x
  enabled: true
  range: 0.000 1.000
  term: low Ramp 1.000 0.000
OutputVariable: y
  range: 0.000 1.000
  aggregation: Maximum
  defuzzifier: Centroid 100
  default: 0.5
  term: a Triangle 0 0.5 1
RuleBlock: rb
  conjunction: none
  disjunction: none
  implication: Minimum
  activation: General
  rule: if x is low then y is a
"""


def test_small_engine_imports_with_default() -> None:
    engine = engine_from_fll("e.fll", text=FLL)
    out = engine.process({"x": [0.0, 1.0]})
    assert out["y"][0] == pytest.approx(0.5)  # symmetric triangle
    assert out["y"][1] == 0.5  # nothing fired: default


@pytest.mark.parametrize(
    ("change", "line", "why"),
    [
        (("term: low Ramp 1.000 0.000", "term: low Ramp 1.000"), 5, "takes 2"),
        (("term: low Ramp 1.000 0.000", "term: low Spike 0.5 1.0"), 5, "unknown fuzzy_term 'Spike'"),
        (("range: 0.000 1.000\n  term: low", "range: 0.000 one\n  term: low"), 4, "expected a number"),
        (("rule: if x is low then y is a", "rule: if x is lo then y is a"), 17, "did you mean 'low'"),
        (("rule: if x is low then y is a", "rule: if x is low and x is low then y is a"), 17, "conjunction is none"),
        (("defuzzifier: Centroid 100", "defuzzifier: Centroyd 100"), 9, "did you mean 'Centroid'"),
        (("  enabled: true\n", "  enabled: false\n"), 3, "disabled"),
        (("  default: 0.5\n", "  default: 0.5\n  lock-previous: true\n"), 11, "lock-previous"),
        (("  activation: General\n", "  activation: Highest\n"), 12, "only General"),
        (("  implication: Minimum\n", "  implication: none\n"), 12, "needs an implication"),
    ],
)
def test_errors_name_the_line(change: tuple[str, str], line: int, why: str) -> None:
    text = FLL.replace(*change)
    assert text != FLL
    with pytest.raises(ConfigError, match=why) as info:
        engine_from_fll("bad.fll", text=text)
    assert info.value.file == "bad.fll"
    assert info.value.line == line


def test_unknown_suffix_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "engine.txt"
    path.write_text(FLL)
    with pytest.raises(ConfigError, match=r"\.yaml, \.yml or \.fll"):
        load_engine(path)
    with pytest.raises(ConfigError, match="file not found"):
        load_engine(tmp_path / "missing.fll")
