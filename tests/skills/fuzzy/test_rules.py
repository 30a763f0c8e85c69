"""The rule language: precedence, parentheses, hedges, weights, and errors with close matches."""

from __future__ import annotations

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.skills.fuzzy.norms import maximum, minimum
from atemr.skills.fuzzy.rules import Operator, Proposition, parse_rule

INPUTS = {"a": ["LOW", "HIGH"], "b": ["LOW", "HIGH"], "c": ["LOW", "HIGH"]}
OUTPUTS = {"y": ["A", "B"], "z": ["A"]}
MU = {("a", "LOW"): 0.2, ("a", "HIGH"): 0.8, ("b", "LOW"): 0.6, ("b", "HIGH"): 0.4, ("c", "LOW"): 0.9,
      ("c", "HIGH"): 0.1}


def degree(text: str) -> float:
    rule = parse_rule(text, INPUTS, OUTPUTS)
    return float(rule.degree(lambda v, t: np.array(MU[(v, t)]), minimum, maximum))


def test_and_binds_tighter_than_or() -> None:
    rule = parse_rule("if a is LOW or b is LOW and c is HIGH then y is A", INPUTS, OUTPUTS)
    assert isinstance(rule.antecedent, Operator) and rule.antecedent.kind == "or"
    # 0.2 or (0.6 and 0.1) = max(0.2, 0.1)
    assert degree("if a is LOW or b is LOW and c is HIGH then y is A") == pytest.approx(0.2)
    # (0.2 or 0.6) and 0.1
    assert degree("if (a is LOW or b is LOW) and c is HIGH then y is A") == pytest.approx(0.1)


def test_hedges_weights_and_several_consequents() -> None:
    rule = parse_rule("if a is not very HIGH then y is B and z is A with 0.5", INPUTS, OUTPUTS)
    assert rule.antecedent == Proposition("a", ("not", "very"), "HIGH")
    assert [str(p) for p in rule.consequents] == ["y is B", "z is A"]
    assert degree("if a is not very HIGH then y is B with 0.5") == pytest.approx(0.5 * (1 - 0.64))


def test_comment_is_ignored() -> None:
    assert parse_rule("if a is LOW then y is A # why", INPUTS, OUTPUTS).consequents[0].term == "A"


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("a is LOW then y is A", "expected 'if'"),
        ("if a is LOW", "expected 'then' but the rule ended"),
        ("if q is LOW then y is A", "unknown input variable 'q'"),
        ("if a is LOUD then y is A", "'a' has no term 'LOUD' .*did you mean 'LOW'"),
        ("if a is LOW then y is C", "'y' has no term 'C'"),
        ("if a is LOW then y is A with x", "must be a number"),
        ("if (a is LOW then y is A", "expected '\\)'"),
        ("if a is LOW then y is A y", "unexpected 'y'"),
        ("if a is LOW then a is LOW", "unknown output variable 'a'"),
    ],
)
def test_errors(text: str, why: str) -> None:
    with pytest.raises(ConfigError, match=why):
        parse_rule(text, INPUTS, OUTPUTS)
