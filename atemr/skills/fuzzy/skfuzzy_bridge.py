"""Build the scikit-fuzzy ``ControlSystem`` that computes the same thing as one of our engines.

scikit-fuzzy is the reference the design names for testing, and its ``ControlSystemSimulation`` is the
baseline of ``benchmarks/bench_fuzzy.py``. It can only express a subset of our engines: Mamdani with
Minimum implication, Minimum/Maximum as and/or, Maximum aggregation and a centroid over a discrete
universe, i.e. outputs with `DiscreteCentroid`; anything else raises `ConfigError` saying what. Input
terms are sampled on ``input_points`` evenly spaced values of each range (scikit-fuzzy interpolates
linearly between them, so piecewise-linear terms with breakpoints on that grid are reproduced exactly).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from atemr.errors import ConfigError
from atemr.skills.fuzzy.discrete_centroid import DiscreteCentroid
from atemr.skills.fuzzy.engine import Engine
from atemr.skills.fuzzy.rules import Expression, Operator, Proposition


def to_skfuzzy(engine: Engine, input_points: int = 121) -> Any:
    """The equivalent ``skfuzzy.control.ControlSystem`` (imported lazily: it needs networkx)."""
    from skfuzzy import control as ctrl

    antecedents = {}
    for var in engine.inputs:
        universe = np.linspace(var.minimum, var.maximum, input_points)
        ant = ctrl.Antecedent(universe, var.name)
        for term in var.terms:
            ant[term.name] = term.membership(universe)
        antecedents[var.name] = ant
    consequents = {}
    for out in engine.outputs:
        if not isinstance(out.defuzzifier, DiscreteCentroid):
            raise ConfigError(f"output '{out.name}': scikit-fuzzy needs a DiscreteCentroid defuzzifier, "
                              f"not {out.defuzzifier.kind}")
        if out.aggregation not in (None, "Maximum"):
            raise ConfigError(f"output '{out.name}': scikit-fuzzy aggregates with Maximum only")
        universe = out.defuzzifier.samples(out.minimum, out.maximum)
        con = ctrl.Consequent(universe, out.name, defuzzify_method="centroid")
        for term in out.terms:
            con[term.name] = term.membership(universe)
        consequents[out.name] = con

    def expression(e: Expression) -> Any:
        if isinstance(e, Proposition):
            if any(h != "not" for h in e.hedges):
                raise ConfigError(f"'{e}': scikit-fuzzy has no hedges other than not")
            term = antecedents[e.variable][e.term]
            return ~term if len(e.hedges) % 2 else term
        assert isinstance(e, Operator)
        left, right = expression(e.left), expression(e.right)
        return left & right if e.kind == "and" else left | right

    rules = []
    for block in engine.rule_blocks:
        ops = (block.conjunction or "Minimum", block.disjunction or "Maximum", block.implication)
        if ops != ("Minimum", "Maximum", "Minimum"):
            raise ConfigError(f"rule block '{block.name}': scikit-fuzzy does Minimum/Maximum/Minimum only, "
                              f"got {'/'.join(str(o) for o in ops)}")
        for rule in block.rules:
            if rule.weight != 1.0 or any(p.hedges for p in rule.consequents):
                raise ConfigError(f"rule '{rule.text}': weights and consequent hedges are not translated")
            rules.append(ctrl.Rule(expression(rule.antecedent),
                                   [consequents[p.variable][p.term] for p in rule.consequents]))
    return ctrl.ControlSystem(rules)
