"""The YAML engine format: a valid engine loads; every mistake names file, line, column and path."""

from __future__ import annotations

from pathlib import Path

import pytest

from atemr.errors import ConfigError
from atemr.skills.fuzzy import load_engine
from atemr.skills.fuzzy.terms import Ramp
from atemr.skills.fuzzy.yaml_format import engine_from_yaml

GOOD = """\
name: demo
type: Mamdani
inputs:
  x:
    range: [0.0, 1.0]
    terms:
      LOW: Ramp 1 0
      HIGH: {type: Ramp, params: [0, 1]}
outputs:
  y:
    range: [0.0, 1.0]
    aggregation: Maximum
    defuzzifier: {type: Centroid, resolution: 100}
    default: .nan
    terms:
      A: Triangle 0 0.25 0.5
      B: Triangle 0.5 0.75 1.0
rule_blocks:
  - name: main
    conjunction: Minimum
    disjunction: Maximum
    implication: Minimum
    rules:
      - if x is LOW then y is A
      - if x is HIGH then y is B
"""


def test_good_engine_loads(tmp_path: Path) -> None:
    path = tmp_path / "demo.yaml"
    path.write_text(GOOD)
    engine = load_engine(path)
    assert engine.name == "demo" and engine.type == "Mamdani"
    assert engine.inputs[0].terms[1] == Ramp("HIGH", (0.0, 1.0))
    out = engine.process({"x": [0.0, 1.0]})
    assert out["y"][0] == pytest.approx(0.25) and out["y"][1] == pytest.approx(0.75)


@pytest.mark.parametrize(
    ("old", "new", "line", "why"),
    [
        ("    range: [0.0, 1.0]\n    terms:\n      LOW", "    range: [1.0, 0.0]\n    terms:\n      LOW", 5,
         "must be below"),
        ("      LOW: Ramp 1 0", "      LOW: Ramp 1", 7, "takes 2"),
        ("      LOW: Ramp 1 0", "      LOW: Ramp 1 zero", 7, "expected a number"),
        ("      LOW: Ramp 1 0", "      LOW: Trapezium 0 0 1 1", 7, "unknown fuzzy_term"),
        ("    aggregation: Maximum", "    aggregation: Maximun", 12, "did you mean 'Maximum'"),
        ("{type: Centroid, resolution: 100}", "{type: Centroid, resolution: 1}", 13, "resolution must be"),
        ("      - if x is LOW then y is A", "      - if x is LOWW then y is A", 24, "did you mean 'LOW'"),
        ("      - if x is LOW then y is A", "      - if x is LOW then z is A", 24, "unknown output variable 'z'"),
        ("      - if x is LOW then y is A", "      - if x is LOW y is A", 24, "expected 'then'"),
        ("      - if x is LOW then y is A", "      - if x is LOW then y is A with 2", 24, "within"),
        ("    implication: Minimum", "    implication: AlgebraicProduct", 22, "Larsen"),  # type: Mamdani ok
        ("    conjunction: Minimum", "    conjuction: Minimum", 20, "did you mean 'conjunction'"),
        ("type: Mamdani", "type: Tsukamoto", 10, "Tsukamoto engine needs"),
        ("    terms:\n      A:", "    term:\n      A:", 15, "did you mean 'terms'"),
        ("      LOW: Ramp 1 0\n", "      LOW: Ramp 1 0\n      LOW: Ramp 0 1\n", 8, "duplicate key"),
    ],
)
def test_errors_point_at_file_line_and_path(old: str, new: str, line: int, why: str) -> None:
    assert old in GOOD
    text = GOOD.replace(old, new)
    if why == "Larsen":  # a Mamdani engine with product implication is fine; declared Larsen it must be product
        engine_from_yaml("e.yaml", text=text)
        text = GOOD.replace("type: Mamdani", "type: Larsen")
        why, line = "AlgebraicProduct", 22
    with pytest.raises(ConfigError, match=why) as info:
        engine_from_yaml("e.yaml", text=text)
    assert info.value.file == "e.yaml"
    assert info.value.line == line, str(info.value)


def test_missing_sections() -> None:
    with pytest.raises(ConfigError, match="missing 'rule_blocks'"):
        engine_from_yaml("e.yaml", text=GOOD.split("rule_blocks:", maxsplit=1)[0])
    with pytest.raises(ConfigError, match="empty document"):
        engine_from_yaml("e.yaml", text="")


def test_operator_none_refuses_rules_that_need_it() -> None:
    text = GOOD.replace("    conjunction: Minimum", "    conjunction: none").replace(
        "if x is LOW then", "if x is LOW and x is HIGH then"
    )
    with pytest.raises(ConfigError, match="conjunction is none") as info:
        engine_from_yaml("e.yaml", text=text)
    assert info.value.line == 24
